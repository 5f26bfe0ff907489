/* query.h - a request's query options as the daemon stores them ("name=value&name=value"), and
 * the body format a Content-Type names. */
#ifndef SURFD_QUERY_H
#define SURFD_QUERY_H

#include <stddef.h>

/* The value of name in options (the last, when repeated) into out; "" when absent. */
void query_option(const char *options, const char *name, char *out, size_t cap);

/* A media type and the body format it names. */
struct media_format {
    const char *type, *format;
};
/* The format table's entry for content_type (its parameters ignored, case-insensitive): "" when
 * there is no type (the caller sniffs), NULL when the table does not have it (415). */
const char *media_format(const char *content_type, const struct media_format *table, size_t n);

#endif
