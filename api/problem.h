/* problem.h - RFC 9457 problem details, the one shape of every error surfd answers, and the
 * mapping from the core's error codes to HTTP statuses. Strings returned are malloc'd; the
 * caller frees them. */
#ifndef SURFD_PROBLEM_H
#define SURFD_PROBLEM_H

#include "../core/base/err.h"

/* {"type","title","status","detail"[,"errors":[{"pointer","message"}]]}; pointer may be NULL (errors: for 400
 * and 422, and a 404 with a pointer: the unknown id of a list). */
char *problem_json(int status, const char *detail, const char *pointer);
/* SF_EFORMAT -> 400, SF_EINVAL/SF_ELIMIT -> 422, SF_ENOMEM/SF_EBACKEND/SF_EIO -> 500. */
int problem_status(int sf_code);
/* problem_json(problem_status(e->code), e->message, e->pointer) */
char *problem_from_err(const struct sf_err *e);
const char *problem_title(int status);

#endif
