/* err.h - the one error convention of surfd (STYLE.md §4).
 *
 * Functions return int: 0 on success, a negative SF_E* code on failure. Details go into a
 * caller-owned struct sf_err (code, JSON pointer into the request, message) that api/ turns
 * into problem+json in one place. No global error state; a NULL err is allowed everywhere. */
#ifndef SURFD_ERR_H
#define SURFD_ERR_H

#include <stdbool.h>

#define SF_ERRORS(X)                                                   \
    X(SF_EINVAL,   -1, "invalid input")                                \
    X(SF_ENOMEM,   -2, "out of memory")                                \
    X(SF_ELIMIT,   -3, "input exceeds a limit")                        \
    X(SF_EFORMAT,  -4, "unreadable input")                             \
    X(SF_ECANCEL,  -5, "cancelled")                                    \
    X(SF_EIO,      -6, "input/output error")                           \
    X(SF_EBACKEND, -7, "library failure")                             \
    X(SF_ECONFLICT, -8, "conflicts with the resource's state")        \
    X(SF_EDAMAGED, -9, "stored bytes no longer match their sum")     \
    X(SF_ENOTFOUND, -10, "not found")                                 \
    X(SF_EREMOTE,  -11, "a remote system failed")

enum {
    SF_OK = 0,
#define SF_ENUM(name, val, msg) name = val,
    SF_ERRORS(SF_ENUM)
#undef SF_ENUM
};

struct sf_err {
    int code;           /* SF_E*, 0 when unset */
    char pointer[160];  /* JSON pointer into the request ("/objects/3/knots_u"), "" if none */
    char message[320];  /* what is wrong, for a human */
};

/* How a long computation in core/ (which has no threads of its own) is stopped and watched: it
 * calls sf_poll() between steps of its work with the fraction done so far; when poll answers
 * true, it returns SF_ECANCEL as soon as it has let go of what it holds. NULL everywhere: never
 * stops. The daemon's job kinds answer from the job's cancel flag and record the fraction. */
struct sf_progress {
    bool (*poll)(void *ctx, double done); /* done in [0, 1]; true: stop */
    void *ctx;
};
/* 0, or SF_ECANCEL (recorded in err) when pr asks to stop. */
int sf_poll(const struct sf_progress *pr, double done, struct sf_err *err);
/* One step of a computation polled as a stretch [lo, hi] of the whole's progress: the step's
 * {sf_span_poll, &span} passes done on to outer (NULL: never stops) as lo + done * (hi - lo). */
struct sf_span {
    const struct sf_progress *outer;
    double lo, hi;
};
bool sf_span_poll(void *span, double done);

/* Fills err (if not NULL) and returns code. The first failure recorded wins. */
int sf_fail(struct sf_err *err, int code, const char *pointer, const char *fmt, ...)
    __attribute__((format(printf, 4, 5)));
const char *sf_strerror(int code);

#endif
