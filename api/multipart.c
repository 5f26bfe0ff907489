/* multipart.c - multipart/form-data split in place (multipart.h). The boundary is the body's
 * own first line, so the body alone says how it is framed (the stored request needs no headers). */
#include "multipart.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* The first occurrence of needle in hay, or NULL (memmem is a GNU extension). */
static const char *find(const char *hay, size_t n, const char *needle, size_t m)
{
    if (m == 0 || n < m)
        return NULL;
    const char *last = hay + (n - m);
    for (const char *p = hay; p <= last; p++) {
        p = memchr(p, needle[0], (size_t)(last - p) + 1);
        if (!p)
            return NULL;
        if (!memcmp(p, needle, m))
            return p;
    }
    return NULL;
}

bool multipart_sniff(const char *body, size_t len)
{
    if (len < 4 || body[0] != '-' || body[1] != '-')
        return false;
    const char *eol = memchr(body, '\n', len < 200 ? len : 200);
    if (!eol || eol - body <= 2)
        return false;
    for (const char *c = body + 2; c < eol - (eol[-1] == '\r'); c++) /* a boundary is printable (RFC 2046) */
        if ((unsigned char)*c < 0x20 || (unsigned char)*c > 0x7e)
            return false;
    return true;
}

int multipart_split(const char *body, size_t len, struct part **parts, int *n, struct sf_err *err)
{
    *parts = NULL;
    *n = 0;
    if (!multipart_sniff(body, len))
        return sf_fail(err, SF_EFORMAT, "", "not multipart/form-data (the body starts with its boundary line)");
    const char *eol = memchr(body, '\n', len);
    size_t blen = (size_t)(eol - body) - (eol[-1] == '\r');
    char delim[208]; /* CRLF "--" boundary */
    if (blen > 200)
        return sf_fail(err, SF_EFORMAT, "", "a multipart boundary is at most 70 characters");
    delim[0] = '\r', delim[1] = '\n';
    memcpy(delim + 2, body, blen);
    size_t dlen = blen + 2;
    const char *p = eol + 1, *end = body + len;
    int cap = 0;
    for (;;) {
        char where[32];
        snprintf(where, sizeof where, "/parts/%d", *n);
        const char *head_end = find(p, (size_t)(end - p), "\r\n\r\n", 4);
        if (!head_end) {
            free(*parts);
            *parts = NULL;
            return sf_fail(err, SF_EFORMAT, where, "a part's headers do not end");
        }
        const char *data = head_end + 4, *next = find(data, (size_t)(end - data), delim, dlen);
        if (!next) {
            free(*parts);
            *parts = NULL;
            return sf_fail(err, SF_EFORMAT, where, "a part is cut short (no closing boundary)");
        }
        if (*n == MULTIPART_MAX_PARTS) {
            free(*parts);
            *parts = NULL;
            return sf_fail(err, SF_ELIMIT, where, "at most %d parts", MULTIPART_MAX_PARTS);
        }
        if (*n == cap) {
            cap = cap ? 2 * cap : 64;
            struct part *more = realloc(*parts, sizeof **parts * (size_t)cap);
            if (!more) {
                free(*parts);
                *parts = NULL;
                return sf_fail(err, SF_ENOMEM, "", "out of memory");
            }
            *parts = more;
        }
        struct part *pt = &(*parts)[(*n)++];
        pt->data = data;
        pt->len = (size_t)(next - data);
        pt->filename = NULL, pt->filename_len = 0;
        const char *fn = find(p, (size_t)(head_end - p), "filename=\"", 10);
        const char *q = fn ? memchr(fn + 10, '"', (size_t)(head_end - fn - 10)) : NULL;
        if (q)
            pt->filename = fn + 10, pt->filename_len = (size_t)(q - fn - 10);
        p = next + dlen;
        if (end - p >= 2 && p[0] == '-' && p[1] == '-')
            return 0; /* the closing boundary */
        if (end - p < 2 || p[0] != '\r' || p[1] != '\n') {
            free(*parts);
            *parts = NULL;
            return sf_fail(err, SF_EFORMAT, where, "a boundary line is not followed by CRLF");
        }
        p += 2;
    }
}
