/* fuzz_multipart.c - api/multipart.c: the input's first byte picks a chunk size (1-256), the rest
 * is a multipart body framed by its own first line (as a posted series is). The streaming reader
 * fed whole and fed in those chunks must see the same parts, headers and bytes and end the same
 * way, and multipart_split must agree with both; the input as a Content-Type is parsed too. A
 * disagreement aborts. */
#include "../../api/multipart.h"
#include "fuzz.h"

#define FUZZ_MAX_PARTS 64

struct trace {
    int n_begun, n_ended;
    uint64_t hash[FUZZ_MAX_PARTS];  /* FNV-1a of each part's header block and bytes */
    uint64_t len[FUZZ_MAX_PARTS];
};

static uint64_t fnv(uint64_t h, const char *p, size_t n)
{
    for (size_t i = 0; i < n; i++)
        h = (h ^ (unsigned char)p[i]) * 1099511628211u;
    return h;
}

static int t_begin(void *ctx, const char *head, size_t head_len, uint64_t head_at, uint64_t data_at,
                   struct sf_err *err)
{
    (void)head_at, (void)data_at, (void)err;
    struct trace *t = ctx;
    if (head[head_len] != 0) /* NUL-terminated where it says */
        abort();
    if (t->n_begun < FUZZ_MAX_PARTS)
        t->hash[t->n_begun] = fnv(14695981039346656037u, head, head_len), t->len[t->n_begun] = 0;
    t->n_begun++;
    return 0;
}

static int t_data(void *ctx, const char *data, size_t len, struct sf_err *err)
{
    (void)err;
    struct trace *t = ctx;
    if (len == 0 || t->n_begun == 0 || t->n_ended != t->n_begun - 1)
        abort(); /* bytes only inside a part, never empty pieces */
    int k = t->n_begun - 1;
    if (k < FUZZ_MAX_PARTS)
        t->hash[k] = fnv(t->hash[k], data, len), t->len[k] += len;
    return 0;
}

static int t_end(void *ctx, struct sf_err *err)
{
    (void)err;
    struct trace *t = ctx;
    if (++t->n_ended != t->n_begun)
        abort();
    return 0;
}

static int run(const char *b, size_t blen, const char *body, size_t len, size_t chunk, struct trace *t)
{
    struct multipart_events ev = {t_begin, t_data, t_end, t};
    struct multipart_reader *r;
    struct sf_err err = {0};
    int rc = multipart_reader_new(b, blen, &ev, &r, &err);
    if (rc)
        return rc;
    for (size_t at = 0; !rc && at < len; at += chunk)
        rc = multipart_reader_feed(r, body + at, len - at < chunk ? len - at : chunk, &err);
    if (!rc)
        rc = multipart_reader_finish(r, &err);
    multipart_reader_free(r);
    return rc;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 1)
        return 0;
    size_t chunk = (size_t)data[0] + 1, len = size - 1;
    char *body = fuzz_text(data + 1, len); /* a copy of its own: ASan sees a read past its end */
    if (!body)
        return 0;
    char out[128];
    multipart_param(body, "boundary", out, sizeof out);
    multipart_is_type(body, "multipart/related");
    struct part *parts = NULL;
    int n = 0;
    struct sf_err err = {0};
    int split_rc = multipart_split(body, len, &parts, &n, &err);
    if (multipart_sniff(body, len)) {
        const char *eol = memchr(body, '\n', len);
        size_t blen = (size_t)(eol - body) - 2 - (eol[-1] == '\r');
        struct trace whole = {0}, cut = {0};
        int rc1 = run(body + 2, blen, body, len, len ? len : 1, &whole);
        int rc2 = run(body + 2, blen, body, len, chunk, &cut);
        if (rc1 != SF_ENOMEM && rc2 != SF_ENOMEM && split_rc != SF_ENOMEM) {
            if (rc1 != rc2 || whole.n_begun != cut.n_begun || whole.n_ended != cut.n_ended)
                abort();
            for (int k = 0; k < whole.n_begun && k < FUZZ_MAX_PARTS; k++)
                if (whole.hash[k] != cut.hash[k] || whole.len[k] != cut.len[k])
                    abort();
            if ((split_rc == 0) != (rc1 == 0 && whole.n_begun <= MULTIPART_MAX_PARTS))
                abort();
            for (int k = 0; split_rc == 0 && k < n && k < FUZZ_MAX_PARTS; k++)
                if (parts[k].len != whole.len[k] || parts[k].data < body || parts[k].data + parts[k].len > body + len)
                    abort();
        }
    }
    free(parts);
    free(body);
    return 0;
}
