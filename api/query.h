/* query.h - a request's query options as the daemon stores them: "name=value&name=value". */
#ifndef SURFD_QUERY_H
#define SURFD_QUERY_H

#include <stddef.h>

/* The value of name in options (the last, when repeated) into out; "" when absent. */
void query_option(const char *options, const char *name, char *out, size_t cap);

#endif
