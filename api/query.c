/* query.c - query options (query.h). */
#include "query.h"

#include <stdio.h>
#include <string.h>

void query_option(const char *options, const char *name, char *out, size_t cap)
{
    out[0] = 0;
    size_t n = strlen(name);
    for (const char *p = options ? options : ""; *p;) {
        size_t len = strcspn(p, "&");
        if (len > n && !strncmp(p, name, n) && p[n] == '=')
            snprintf(out, cap, "%.*s", (int)(len - n - 1), p + n + 1);
        p += len + (p[len] == '&');
    }
}
