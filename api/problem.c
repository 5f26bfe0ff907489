/* problem.c - problem+json bodies (RFC 9457) built with jansson, so every string is escaped. */
#include "problem.h"

#include <jansson.h>
#include <stdio.h>

const char *problem_title(int status)
{
    switch (status) {
    case 400: return "Bad Request";
    case 401: return "Unauthorized";
    case 404: return "Not Found";
    case 405: return "Method Not Allowed";
    case 409: return "Conflict";
    case 410: return "Gone";
    case 413: return "Content Too Large";
    case 414: return "URI Too Long";
    case 415: return "Unsupported Media Type";
    case 422: return "Unprocessable Content";
    case 403: return "Forbidden";
    case 429: return "Too Many Requests";
    case 501: return "Not Implemented";
    case 502: return "Bad Gateway";
    case 503: return "Service Unavailable";
    default: return status >= 500 ? "Internal Server Error" : "Error";
    }
}

int problem_status(int sf_code)
{
    switch (sf_code) {
    case SF_EFORMAT: return 400;
    case SF_EINVAL:
    case SF_ELIMIT: return 422;
    case SF_ECONFLICT: return 409;
    case SF_ENOTFOUND: return 404;
    case SF_EREMOTE: return 502; /* a PACS down or failing: not surfd's own error */
    default: return 500;
    }
}

char *problem_json(int status, const char *detail, const char *pointer)
{
    char type[96];
    snprintf(type, sizeof type, "https://surfd.invalid/problems/%d", status);
    json_t *o = json_pack("{s:s, s:s, s:i, s:s}", "type", type, "title", problem_title(status), "status", status,
                          "detail", detail ? detail : "");
    if (o && pointer && (status == 422 || status == 400 || ((status == 404 || status == 410) && *pointer))) {
        /* (404: which id of a list; 410: the version asked for) */
        json_t *e = json_pack("[{s:s, s:s}]", "pointer", pointer, "message", detail ? detail : "");
        if (e)
            json_object_set_new(o, "errors", e);
    }
    char *s = o ? json_dumps(o, JSON_COMPACT) : NULL;
    json_decref(o);
    return s;
}

char *problem_from_err(const struct sf_err *e)
{
    return problem_json(problem_status(e->code), e->message[0] ? e->message : sf_strerror(e->code), e->pointer);
}
