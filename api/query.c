/* query.c - query options (query.h). */
#include "query.h"

#include <ctype.h>
#include <stdio.h>
#include <string.h>
#include <strings.h>

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

const char *media_format(const char *ct, const struct media_format *table, size_t n)
{
    if (!ct || !*ct)
        return "";
    size_t len = strcspn(ct, ";");
    while (len > 0 && isspace((unsigned char)ct[len - 1]))
        len--;
    for (size_t k = 0; k < n; k++)
        if (strlen(table[k].type) == len && !strncasecmp(ct, table[k].type, len))
            return table[k].format;
    return NULL;
}
