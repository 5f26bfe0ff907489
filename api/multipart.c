/* multipart.c - multipart bodies (multipart.h): one streaming reader, and the in-place split of a
 * posted series on top of it (the body fed at once, so every part's bytes arrive in one piece and
 * point into the body). The boundary of a form-data upload is the body's own first line, so the
 * body alone says how it is framed (the stored request needs no headers); a DICOMweb answer's is
 * its Content-Type's.
 *
 * The reader's states (each byte moves at most one step; feed makes every transition):
 *
 *   PREAMBLE --delimiter--> AFTER_DELIM --"--"--> EPILOGUE (finish answers 0)
 *                              |  (padding) CRLF or LF
 *                              v
 *   DATA <--empty line-- HEAD
 *     `--delimiter (part_end)--> AFTER_DELIM          any error --> FAILED
 *
 * The delimiter is CRLF "--" boundary (RFC 2046 5.1.1); a boundary is printable ASCII, so a CR
 * only ever starts one, and bytes held back as a possible delimiter at a chunk's end are a prefix
 * of it: on a mismatch they are the part's data, and the search goes on from the byte that broke
 * the match (no backtracking table needed). The body's first delimiter may open it without the
 * CRLF: the reader starts as if that CRLF had been read. */
#include "multipart.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

enum mp_state { MP_PREAMBLE, MP_AFTER_DELIM, MP_PADDING, MP_CLOSING, MP_LF, MP_HEAD, MP_DATA, MP_EPILOGUE, MP_FAILED };

struct multipart_reader {
    struct multipart_events ev;
    enum mp_state state;
    int fail_code;                            /* the code every feed answers once FAILED */
    char delim[MULTIPART_MAX_BOUNDARY + 4];   /* CRLF "--" boundary */
    size_t dlen;
    size_t matched;                           /* bytes of delim matched by the last ones fed (held back) */
    uint64_t pos;                             /* offset of the next byte fed */
    int n_parts;                              /* parts begun */
    uint64_t head_at;
    size_t hlen;
    char head[MULTIPART_MAX_HEAD + 1];        /* the header block being read, NUL-terminated for part_begin */
};

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

static bool is_ows(char c) { return c == ' ' || c == '\t'; }

bool multipart_is_type(const char *content_type, const char *type)
{
    if (!content_type)
        return false;
    while (is_ows(*content_type))
        content_type++;
    size_t n = strlen(type);
    char after = content_type[strncasecmp(content_type, type, n) ? 0 : n];
    return !strncasecmp(content_type, type, n) && (after == 0 || after == ';' || is_ows(after));
}

bool multipart_param(const char *content_type, const char *name, char *out, size_t cap)
{
    size_t nlen = strlen(name);
    const char *p = content_type ? strchr(content_type, ';') : NULL;
    while (p) {
        p++;
        while (is_ows(*p))
            p++;
        const char *key = p;
        while (*p && *p != '=' && *p != ';' && !is_ows(*p))
            p++;
        bool match = (size_t)(p - key) == nlen && !strncasecmp(key, name, nlen);
        while (is_ows(*p))
            p++;
        if (*p != '=') {
            p = strchr(p, ';');
            continue;
        }
        p++;
        while (is_ows(*p))
            p++;
        size_t n = 0;
        bool quoted = *p == '"';
        if (quoted) {
            for (p++; *p && *p != '"'; p++) {
                if (*p == '\\' && p[1])
                    p++;
                if (match && n + 1 < cap)
                    out[n] = *p;
                n += match;
            }
            if (*p != '"')
                return false; /* an unclosed quoted string: nothing after it can be trusted */
            p++;
        } else {
            for (; *p && *p != ';' && !is_ows(*p); p++) {
                if (match && n + 1 < cap)
                    out[n] = *p;
                n += match;
            }
        }
        if (match) {
            if (n + 1 > cap)
                return false;
            out[n] = 0;
            return true;
        }
        p = strchr(p, ';');
    }
    return false;
}

int multipart_reader_new(const char *boundary, size_t blen, const struct multipart_events *ev,
                         struct multipart_reader **out, struct sf_err *err)
{
    *out = NULL;
    if (blen == 0 || blen > MULTIPART_MAX_BOUNDARY)
        return sf_fail(err, SF_EINVAL, "", "a multipart boundary has 1 to %d characters", MULTIPART_MAX_BOUNDARY);
    for (size_t i = 0; i < blen; i++)
        if ((unsigned char)boundary[i] < 0x20 || (unsigned char)boundary[i] > 0x7e)
            return sf_fail(err, SF_EINVAL, "", "a multipart boundary is printable ASCII");
    struct multipart_reader *r = malloc(sizeof *r);
    if (!r)
        return sf_fail(err, SF_ENOMEM, "", "out of memory");
    r->ev = *ev;
    r->state = MP_PREAMBLE;
    r->fail_code = 0;
    memcpy(r->delim, "\r\n--", 4);
    memcpy(r->delim + 4, boundary, blen);
    r->dlen = blen + 4;
    r->matched = 2; /* the body may open with its first delimiter: as if after a CRLF */
    r->pos = 0;
    r->n_parts = 0;
    r->head_at = 0;
    r->hlen = 0;
    *out = r;
    return 0;
}

void multipart_reader_free(struct multipart_reader *r)
{
    free(r);
}

int multipart_reader_parts(const struct multipart_reader *r)
{
    return r->n_parts;
}

static int reader_fail(struct multipart_reader *r, int code, struct sf_err *err, const char *msg)
{
    if (msg) {
        char where[32];
        snprintf(where, sizeof where, "/parts/%d", r->n_parts - (r->state == MP_HEAD || r->state == MP_DATA));
        sf_fail(err, code, where, "%s", msg);
    }
    r->state = MP_FAILED;
    r->fail_code = code;
    return code;
}

static int emit(struct multipart_reader *r, const char *data, size_t len, struct sf_err *err)
{
    int rc = r->state == MP_DATA && len && r->ev.part_data ? r->ev.part_data(r->ev.ctx, data, len, err) : 0;
    return rc ? reader_fail(r, rc, err, NULL) : 0;
}

/* Reads data[*i..len) in PREAMBLE or DATA up to and including the next delimiter, handing DATA's
 * bytes on. 1 when the delimiter ended (*i past it), 0 when the bytes ran out first, or an error. */
static int scan_delim(struct multipart_reader *r, const char *data, size_t len, size_t *i, struct sf_err *err)
{
    int rc;
    for (;;) {
        if (r->matched == 0) {
            const char *cr = memchr(data + *i, '\r', len - *i);
            size_t stop = cr ? (size_t)(cr - data) : len;
            if ((rc = emit(r, data + *i, stop - *i, err)))
                return rc;
            *i = stop;
            if (!cr)
                return 0;
        }
        size_t held = r->matched, from = *i;
        while (*i < len && r->matched < r->dlen && data[*i] == r->delim[r->matched])
            (*i)++, r->matched++;
        if (r->matched == r->dlen) {
            r->matched = 0;
            return 1;
        }
        if (*i == len)
            return 0;
        /* a mismatch: what was held and what matched since are data (no CR among them but the first) */
        r->matched = 0;
        if ((held && (rc = emit(r, r->delim, held, err))) || (rc = emit(r, data + from, *i - from, err)))
            return rc;
    }
}

static void begin_head(struct multipart_reader *r, uint64_t at)
{
    r->state = MP_HEAD;
    r->n_parts++;
    r->head_at = at;
    r->hlen = 0;
}

/* One byte of a header block; data_at: the offset after it. */
static int head_byte(struct multipart_reader *r, char c, uint64_t data_at, struct sf_err *err)
{
    if (r->hlen == MULTIPART_MAX_HEAD)
        return reader_fail(r, SF_ELIMIT, err, "a part's header block is over 16 KB");
    r->head[r->hlen++] = c;
    size_t head_len;
    if (r->hlen == 2 && !memcmp(r->head, "\r\n", 2))
        head_len = 0; /* no header lines */
    else if (r->hlen >= 4 && !memcmp(r->head + r->hlen - 4, "\r\n\r\n", 4))
        head_len = r->hlen - 4;
    else
        return 0;
    r->head[head_len] = 0;
    r->state = MP_DATA;
    r->matched = 0;
    int rc = r->ev.part_begin ? r->ev.part_begin(r->ev.ctx, r->head, head_len, r->head_at, data_at, err) : 0;
    return rc ? reader_fail(r, rc, err, NULL) : 0;
}

int multipart_reader_feed(struct multipart_reader *r, const char *data, size_t len, struct sf_err *err)
{
    size_t i = 0;
    int rc;
    while (i < len) {
        switch (r->state) {
        case MP_FAILED:
            return r->fail_code;
        case MP_EPILOGUE:
            i = len;
            break;
        case MP_PREAMBLE:
        case MP_DATA:
            rc = scan_delim(r, data, len, &i, err);
            if (rc < 0)
                return rc;
            if (rc == 1) {
                bool ended = r->state == MP_DATA;
                r->state = MP_AFTER_DELIM;
                if (ended && r->ev.part_end && (rc = r->ev.part_end(r->ev.ctx, err)))
                    return reader_fail(r, rc, err, NULL);
            }
            break;
        case MP_AFTER_DELIM:
        case MP_PADDING: {
            char c = data[i++];
            if (c == '-' && r->state == MP_AFTER_DELIM)
                r->state = MP_CLOSING;
            else if (is_ows(c))
                r->state = MP_PADDING; /* transport padding (RFC 2046 5.1.1) */
            else if (c == '\r')
                r->state = MP_LF;
            else if (c == '\n')
                begin_head(r, r->pos + i);
            else
                return reader_fail(r, SF_EFORMAT, err, "a boundary line is not followed by CRLF");
            break;
        }
        case MP_CLOSING:
            if (data[i++] != '-')
                return reader_fail(r, SF_EFORMAT, err, "a boundary line is not followed by CRLF");
            r->state = MP_EPILOGUE;
            break;
        case MP_LF:
            if (data[i++] != '\n')
                return reader_fail(r, SF_EFORMAT, err, "a boundary line is not followed by CRLF");
            begin_head(r, r->pos + i);
            break;
        case MP_HEAD:
            rc = head_byte(r, data[i], r->pos + i + 1, err);
            i++;
            if (rc)
                return rc;
            break;
        }
    }
    r->pos += len;
    return 0;
}

int multipart_reader_finish(struct multipart_reader *r, struct sf_err *err)
{
    switch (r->state) {
    case MP_EPILOGUE:
        return 0;
    case MP_FAILED:
        return r->fail_code;
    case MP_PREAMBLE:
        return reader_fail(r, SF_EFORMAT, err, "no multipart boundary line");
    case MP_HEAD:
        return reader_fail(r, SF_EFORMAT, err, "a part's headers do not end");
    case MP_DATA:
        return reader_fail(r, SF_EFORMAT, err, "a part is cut short (no closing boundary)");
    default:
        return reader_fail(r, SF_EFORMAT, err, "the body ends inside a boundary line");
    }
}

/* multipart_split's events: each part where it lies in the body */
struct split {
    const char *body;
    struct part *parts;
    int n, cap;
};

static int split_begin(void *ctx, const char *head, size_t head_len, uint64_t head_at, uint64_t data_at,
                       struct sf_err *err)
{
    struct split *s = ctx;
    char where[32];
    snprintf(where, sizeof where, "/parts/%d", s->n);
    if (s->n == MULTIPART_MAX_PARTS)
        return sf_fail(err, SF_ELIMIT, where, "at most %d parts", MULTIPART_MAX_PARTS);
    if (s->n == s->cap) {
        int cap = s->cap ? 2 * s->cap : 64;
        struct part *more = realloc(s->parts, sizeof *more * (size_t)cap);
        if (!more)
            return sf_fail(err, SF_ENOMEM, "", "out of memory");
        s->parts = more, s->cap = cap;
    }
    struct part *pt = &s->parts[s->n++];
    pt->data = s->body + data_at;
    pt->len = 0;
    pt->filename = NULL, pt->filename_len = 0;
    const char *fn = find(head, head_len, "filename=\"", 10);
    const char *q = fn ? memchr(fn + 10, '"', head_len - (size_t)(fn + 10 - head)) : NULL;
    if (q) /* the same bytes in the body, where the header block lies */
        pt->filename = s->body + head_at + (size_t)(fn + 10 - head), pt->filename_len = (size_t)(q - fn - 10);
    return 0;
}

static int split_data(void *ctx, const char *data, size_t len, struct sf_err *err)
{
    struct split *s = ctx;
    struct part *pt = &s->parts[s->n - 1];
    if (data != pt->data + pt->len) /* fed at once, a part's bytes come in place and in order */
        return sf_fail(err, SF_EFORMAT, "", "a part's bytes are not where the body has them");
    pt->len += len;
    return 0;
}

int multipart_split(const char *body, size_t len, struct part **parts, int *n, struct sf_err *err)
{
    *parts = NULL;
    *n = 0;
    if (!multipart_sniff(body, len))
        return sf_fail(err, SF_EFORMAT, "", "not multipart/form-data (the body starts with its boundary line)");
    const char *eol = memchr(body, '\n', len);
    size_t blen = (size_t)(eol - body) - 2 - (eol[-1] == '\r');
    if (blen > MULTIPART_MAX_BOUNDARY)
        return sf_fail(err, SF_EFORMAT, "", "a multipart boundary is at most %d characters", MULTIPART_MAX_BOUNDARY);
    struct split s = {body, NULL, 0, 0};
    struct multipart_events ev = {split_begin, split_data, NULL, &s};
    struct multipart_reader *r;
    int rc = multipart_reader_new(body + 2, blen, &ev, &r, err);
    if (rc)
        return rc == SF_EINVAL ? SF_EFORMAT : rc;
    if (!(rc = multipart_reader_feed(r, body, len, err)))
        rc = multipart_reader_finish(r, err);
    multipart_reader_free(r);
    if (rc) {
        free(s.parts);
        return rc;
    }
    *parts = s.parts;
    *n = s.n;
    return 0;
}
