/* test_multipart.c - api/multipart.c: the streaming reader gives every part's bytes exactly, fed
 * whole or cut into chunks anywhere (near-delimiters, a delimiter split across chunks, CR runs);
 * multipart_split agrees with it and points into the body; Content-Type parameters; the caps
 * (header block, boundary) and the broken bodies refused with the part they are in. */
#include <stdint.h>

#include "../../api/multipart.h"
#include "../unit.h"

#define MAX_SEEN 8

/* What the events saw: each part's header block and bytes, concatenated */
struct seen {
    int n_begun, n_ended;
    char head[MAX_SEEN][256];
    char data[MAX_SEEN][512];
    size_t len[MAX_SEEN];
    uint64_t data_at[MAX_SEEN];
    int stop_at;  /* part_begin of this part (1-based) answers SF_ECANCEL; 0: never */
};

static int on_begin(void *ctx, const char *head, size_t head_len, uint64_t head_at, uint64_t data_at,
                    struct sf_err *err)
{
    (void)head_at;
    struct seen *s = ctx;
    if (++s->n_begun == s->stop_at)
        return sf_fail(err, SF_ECANCEL, "", "stopped");
    if (s->n_begun <= MAX_SEEN) {
        snprintf(s->head[s->n_begun - 1], sizeof s->head[0], "%.*s", (int)head_len, head);
        s->data_at[s->n_begun - 1] = data_at;
    }
    return 0;
}

static int on_data(void *ctx, const char *data, size_t len, struct sf_err *err)
{
    (void)err;
    struct seen *s = ctx;
    int k = s->n_begun - 1;
    if (k < MAX_SEEN && s->len[k] + len < sizeof s->data[0]) {
        memcpy(s->data[k] + s->len[k], data, len);
        s->len[k] += len;
    }
    return 0;
}

static int on_end(void *ctx, struct sf_err *err)
{
    (void)err;
    struct seen *s = ctx;
    s->n_ended++;
    return 0;
}

/* Feeds body in chunks of `chunk` bytes (0: whole); the code of the first failing call or finish. */
static int read_body(const char *boundary, const char *body, size_t len, size_t chunk, struct seen *s,
                     struct sf_err *err)
{
    struct multipart_events ev = {on_begin, on_data, on_end, s};
    struct multipart_reader *r;
    int rc = multipart_reader_new(boundary, strlen(boundary), &ev, &r, err);
    if (rc)
        return rc;
    for (size_t at = 0; !rc && at < len; at += chunk ? chunk : len)
        rc = multipart_reader_feed(r, body + at, chunk && len - at > chunk ? chunk : len - at, err);
    if (!rc)
        rc = multipart_reader_finish(r, err);
    multipart_reader_free(r);
    return rc;
}

/* Three parts whose bytes hold what a delimiter starts with: CRLF, CRLF "--", the boundary but one
 * character, a CR run; the second part has no header lines; a preamble and an epilogue. */
static const char TRICKY[] =
    "preamble\r\n--b0undary\r\n"
    "Content-Type: application/dicom\r\n\r\n"
    "one\r\n--b0undar\r\r\n--b0undarX\r\n-\r\r\r\n--\r\n"
    "\r\n--b0undary  \r\n"  /* transport padding after a delimiter */
    "\r\n"
    "two\r"
    "\r\n--b0undary\r\n"
    "Content-Type: application/dicom\r\nContent-Length: 5\r\n\r\n"
    "three"
    "\r\n--b0undary--\r\nepilogue \r\n--b0undary\r\n";

TEST(every_chunking_gives_the_same_parts)
{
    size_t len = sizeof TRICKY - 1;
    const char *one = "one\r\n--b0undar\r\r\n--b0undarX\r\n-\r\r\r\n--\r\n";
    for (size_t chunk = 0; chunk <= len; chunk++) {
        struct seen s = {0};
        struct sf_err err = {0};
        int rc = read_body("b0undary", TRICKY, len, chunk, &s, &err);
        CHECK(rc == 0);
        if (rc) {
            fprintf(stderr, "  chunk %zu: %s %s\n", chunk, err.pointer, err.message);
            return;
        }
        CHECK(s.n_begun == 3 && s.n_ended == 3);
        CHECK(s.len[0] == strlen(one) && !memcmp(s.data[0], one, s.len[0]));
        CHECK(s.len[1] == 4 && !memcmp(s.data[1], "two\r", 4));
        CHECK(s.len[2] == 5 && !memcmp(s.data[2], "three", 5));
        CHECK_STR(s.head[0], "Content-Type: application/dicom");
        CHECK_STR(s.head[1], "");
        CHECK_STR(s.head[2], "Content-Type: application/dicom\r\nContent-Length: 5");
        CHECK(s.data_at[2] == (uint64_t)(strstr(TRICKY, "three") - TRICKY));
    }
}

TEST(split_points_into_the_body)
{
    static const char body[] = "--XyZ\r\n"
                               "Content-Disposition: form-data; name=\"slice\"; filename=\"IM0001.dcm\"\r\n\r\n"
                               "AB\r\nC"
                               "\r\n--XyZ\r\n"
                               "Content-Disposition: form-data; name=\"slice\"\r\n\r\n"
                               ""
                               "\r\n--XyZ--\r\n";
    struct part *parts;
    int n;
    struct sf_err err = {0};
    REQUIRE(multipart_split(body, sizeof body - 1, &parts, &n, &err) == 0);
    CHECK(n == 2);
    CHECK(parts[0].data == strstr(body, "AB\r\nC") && parts[0].len == 5);
    CHECK(parts[0].filename == strstr(body, "IM0001") && parts[0].filename_len == 10);
    CHECK(parts[1].len == 0 && parts[1].filename == NULL);
    free(parts);
}

TEST(split_refuses_what_is_cut_short)
{
    static const char cut[] = "--XyZ\r\nContent-Type: x\r\n\r\nabc\r\n--XyZ\r\nContent-Type: x\r\n\r\nde";
    static const char nohead[] = "--XyZ\r\nContent-Type: x\r\n";
    static const char badline[] = "--XyZ\r\n\r\na\r\n--XyZ!\r\n\r\nb\r\n--XyZ--";
    struct part *parts = (struct part *)1;
    int n = 1;
    struct sf_err err = {0};
    CHECK(multipart_split(cut, sizeof cut - 1, &parts, &n, &err) == SF_EFORMAT);
    CHECK(parts == NULL && n == 0);
    CHECK_STR(err.pointer, "/parts/1");
    struct sf_err err2 = {0};
    CHECK(multipart_split(nohead, sizeof nohead - 1, &parts, &n, &err2) == SF_EFORMAT);
    CHECK_STR(err2.pointer, "/parts/0");
    struct sf_err err3 = {0};
    CHECK(multipart_split(badline, sizeof badline - 1, &parts, &n, &err3) == SF_EFORMAT);
    CHECK(strstr(err3.message, "CRLF") != NULL);
    struct sf_err err4 = {0};
    CHECK(multipart_split("not multipart", 13, &parts, &n, &err4) == SF_EFORMAT);
}

TEST(a_header_block_over_the_cap_is_refused)
{
    size_t len = 20 + MULTIPART_MAX_HEAD + 100;
    char *body = malloc(len);
    REQUIRE(body);
    size_t n = (size_t)sprintf(body, "--b\r\nX-Long: ");
    memset(body + n, 'a', len - n);
    struct seen s = {0};
    struct sf_err err = {0};
    CHECK(read_body("b", body, len, 4096, &s, &err) == SF_ELIMIT);
    CHECK_STR(err.pointer, "/parts/0");
    CHECK(s.n_begun == 0);
    /* just under the cap: read */
    size_t head = MULTIPART_MAX_HEAD - 4; /* the header block with its CRLF CRLF */
    n = (size_t)sprintf(body, "--b\r\nX: ");
    memset(body + n, 'a', head - 3);
    n += head - 3;
    n += (size_t)sprintf(body + n, "\r\n\r\nz\r\n--b--");
    struct seen s2 = {0};
    struct sf_err err2 = {0};
    CHECK(read_body("b", body, n, 1000, &s2, &err2) == 0);
    CHECK(s2.n_begun == 1 && s2.len[0] == 1);
    free(body);
}

TEST(an_event_stops_the_reader)
{
    struct seen s = {.stop_at = 2};
    struct sf_err err = {0};
    CHECK(read_body("b0undary", TRICKY, sizeof TRICKY - 1, 7, &s, &err) == SF_ECANCEL);
    CHECK(s.n_ended == 1);
    CHECK_STR(err.message, "stopped");
}

TEST(a_body_without_its_closing_delimiter_fails_at_finish)
{
    static const char body[] = "--b\r\n\r\nabc\r\n--b\r\n\r\ndef\r\n--b";
    struct seen s = {0};
    struct sf_err err = {0};
    CHECK(read_body("b", body, sizeof body - 1, 3, &s, &err) == SF_EFORMAT);
    CHECK(s.n_ended == 2); /* both parts ended; the line after the last delimiter never came */
    struct seen s2 = {0};
    struct sf_err err2 = {0};
    CHECK(read_body("b", "no delimiter at all", 19, 0, &s2, &err2) == SF_EFORMAT);
    CHECK(s2.n_begun == 0);
}

TEST(boundaries_are_checked)
{
    struct multipart_events ev = {0};
    struct multipart_reader *r = NULL;
    char big[MULTIPART_MAX_BOUNDARY + 2];
    memset(big, 'a', sizeof big);
    struct sf_err err = {0};
    CHECK(multipart_reader_new(big, sizeof big, &ev, &r, &err) == SF_EINVAL && r == NULL);
    CHECK(multipart_reader_new("a\rb", 3, &ev, &r, NULL) == SF_EINVAL);
    CHECK(multipart_reader_new("", 0, &ev, &r, NULL) == SF_EINVAL);
    CHECK(multipart_reader_new(big, MULTIPART_MAX_BOUNDARY, &ev, &r, NULL) == 0 && r);
    multipart_reader_free(r);
    multipart_reader_free(NULL);
}

TEST(content_type_parameters)
{
    char out[80];
    const char *ct = "Multipart/Related; type=\"application/dicom\"; BOUNDARY=\"a;b \\\"c\\\"\"; x=1";
    CHECK(multipart_is_type(ct, "multipart/related"));
    CHECK(!multipart_is_type(ct, "multipart/relate"));
    CHECK(!multipart_is_type(NULL, "multipart/related"));
    CHECK(multipart_param(ct, "boundary", out, sizeof out) && !strcmp(out, "a;b \"c\""));
    CHECK(multipart_param(ct, "type", out, sizeof out) && !strcmp(out, "application/dicom"));
    CHECK(multipart_param(ct, "x", out, sizeof out) && !strcmp(out, "1"));
    CHECK(!multipart_param(ct, "missing", out, sizeof out));
    CHECK(!multipart_param(ct, "boundary", out, 4)); /* does not fit */
    CHECK(multipart_param("multipart/related;boundary=abc", "boundary", out, sizeof out) && !strcmp(out, "abc"));
    CHECK(!multipart_param("multipart/related; boundary=\"abc", "boundary", out, sizeof out)); /* unclosed */
    CHECK(!multipart_param("multipart/related; boundaryx=abc", "boundary", out, sizeof out));
    CHECK(multipart_is_type(" application/dicom; transfer-syntax=*", "application/dicom"));
}

int main(void)
{
    RUN(every_chunking_gives_the_same_parts);
    RUN(split_points_into_the_body);
    RUN(split_refuses_what_is_cut_short);
    RUN(a_header_block_over_the_cap_is_refused);
    RUN(an_event_stops_the_reader);
    RUN(a_body_without_its_closing_delimiter_fails_at_finish);
    RUN(boundaries_are_checked);
    RUN(content_type_parameters);
    UNIT_END();
}
