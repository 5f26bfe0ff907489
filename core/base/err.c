/* err.c - the error table and the one place errors are recorded. */
#include "err.h"

#include <stdarg.h>
#include <stdio.h>
#include <string.h>

int sf_fail(struct sf_err *err, int code, const char *pointer, const char *fmt, ...)
{
    if (!err || err->code)
        return code;
    err->code = code;
    snprintf(err->pointer, sizeof err->pointer, "%s", pointer ? pointer : "");
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(err->message, sizeof err->message, fmt, ap);
    va_end(ap);
    return code;
}

const char *sf_strerror(int code)
{
    switch (code) {
    case SF_OK: return "ok";
#define SF_CASE(name, val, msg) case name: return msg;
    SF_ERRORS(SF_CASE)
#undef SF_CASE
    }
    return "unknown error";
}

bool sf_span_poll(void *span, double done)
{
    const struct sf_span *s = span;
    return sf_poll(s->outer, s->lo + done * (s->hi - s->lo), NULL) != 0;
}

int sf_poll(const struct sf_progress *pr, double done, struct sf_err *err)
{
    if (!pr || !pr->poll || !pr->poll(pr->ctx, done < 0 ? 0 : done > 1 ? 1 : done))
        return 0;
    return sf_fail(err, SF_ECANCEL, "", "cancelled");
}
