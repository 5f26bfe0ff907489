/* test_j2k.c - JPEG 2000 frames (api/j2k.h): codestreams made here by OpenJPEG's own encoder
 * (reversible 5/3 wavelet: lossless) decode to the samples they were made from, 16-bit unsigned,
 * 12-bit signed and 8-bit, tiled or not; a stream of another size, precision, sign or component
 * count than the frame declares, one claiming too many tiles, a truncated one and one of garbage
 * after its header are refused at the frame's pointer, each before or while OpenJPEG reads it. */
#include "../../api/j2k.h"
#include "../unit.h"

#include <openjpeg.h>
#include <stdlib.h>
#include <string.h>

struct buf {
    unsigned char *p;
    size_t n, cap;
};

static OPJ_SIZE_T buf_write(void *data, OPJ_SIZE_T n, void *user)
{
    struct buf *b = user;
    if (b->n + n > b->cap) {
        size_t cap = 2 * (b->n + n);
        unsigned char *p = realloc(b->p, cap);
        if (!p)
            return (OPJ_SIZE_T)-1;
        b->p = p, b->cap = cap;
    }
    memcpy(b->p + b->n, data, n);
    b->n += n;
    return n;
}

static OPJ_BOOL buf_seek(OPJ_OFF_T at, void *user)
{
    struct buf *b = user;
    if (at < 0 || (size_t)at > b->n)
        return OPJ_FALSE;
    b->n = (size_t)at;
    return OPJ_TRUE;
}

static OPJ_OFF_T buf_skip(OPJ_OFF_T n, void *user)
{
    struct buf *b = user;
    unsigned char zero[256] = {0};
    for (OPJ_OFF_T k = 0; k < n; k += 256)
        if (buf_write(zero, (OPJ_SIZE_T)(n - k < 256 ? n - k : 256), b) == (OPJ_SIZE_T)-1)
            return -1;
    return n;
}

/* A lossless J2K codestream of one component (rows x cols, prec bits, signed or not), tiles of
 * tile x tile (0: one). */
static struct buf encode(const int32_t *v, int rows, int cols, int prec, bool sgnd, int tile)
{
    struct buf b = {0};
    opj_image_cmptparm_t cp = {.dx = 1, .dy = 1, .w = (OPJ_UINT32)cols, .h = (OPJ_UINT32)rows, .prec = (OPJ_UINT32)prec,
                               .sgnd = sgnd};
    opj_image_t *img = opj_image_create(1, &cp, OPJ_CLRSPC_GRAY);
    img->x1 = (OPJ_UINT32)cols, img->y1 = (OPJ_UINT32)rows;
    memcpy(img->comps[0].data, v, sizeof *v * (size_t)rows * (size_t)cols);
    opj_cparameters_t par;
    opj_set_default_encoder_parameters(&par);
    par.irreversible = 0;
    par.numresolution = 3;
    if (tile) {
        par.tile_size_on = OPJ_TRUE;
        par.cp_tdx = par.cp_tdy = tile;
    }
    opj_codec_t *c = opj_create_compress(OPJ_CODEC_J2K);
    opj_stream_t *s = opj_stream_create(1 << 16, OPJ_FALSE);
    opj_stream_set_user_data(s, &b, NULL);
    opj_stream_set_write_function(s, buf_write);
    opj_stream_set_seek_function(s, buf_seek);
    opj_stream_set_skip_function(s, buf_skip);
    bool ok = opj_setup_encoder(c, &par, img) && opj_start_compress(c, img, s) && opj_encode(c, s) &&
              opj_end_compress(c, s);
    opj_stream_destroy(s);
    opj_destroy_codec(c);
    opj_image_destroy(img);
    if (!ok)
        free(b.p), b = (struct buf){0};
    return b;
}

static int32_t *samples(int rows, int cols, int prec, bool sgnd)
{
    int32_t *v = malloc(sizeof *v * (size_t)rows * (size_t)cols), lo = sgnd ? -(1 << (prec - 1)) : 0;
    uint32_t span = 1u << prec, state = 12345;
    for (int i = 0; i < rows * cols; i++) {
        state = state * 1103515245u + 12345u;
        int y = i / cols, x = i % cols;
        v[i] = lo + (int32_t)(((uint32_t)(x * 37 + y * 11) + (state >> 24)) % span); /* (a ramp with noise) */
    }
    return v;
}

TEST(decodes_what_was_encoded)
{
    const struct {
        int rows, cols, prec;
        bool sgnd;
        int tile;
    } cases[] = {{64, 48, 16, false, 0}, {37, 53, 12, true, 0}, {40, 40, 8, false, 16}, {30, 70, 16, true, 32}};
    for (size_t k = 0; k < sizeof cases / sizeof *cases; k++) {
        int rows = cases[k].rows, cols = cases[k].cols, prec = cases[k].prec;
        int32_t *v = samples(rows, cols, prec, cases[k].sgnd);
        struct buf b = encode(v, rows, cols, prec, cases[k].sgnd, cases[k].tile);
        REQUIRE(b.p != NULL);
        uint16_t *out = calloc((size_t)rows * cols, sizeof *out);
        struct sf_err err = {0};
        struct j2k_frame f = {rows, cols, prec, cases[k].sgnd};
        CHECK(j2k_decode(b.p, b.n, &f, out, "/parts/0", &err) == 0);
        int same = 0;
        for (int i = 0; i < rows * cols; i++)
            same += (cases[k].sgnd ? (int32_t)(int16_t)out[i] : (int32_t)out[i]) == v[i];
        fprintf(stderr, "  %d x %d, %d bits %s, tiles %d: %d of %d samples back, %zu bytes\n", rows, cols, prec,
                cases[k].sgnd ? "signed" : "unsigned", cases[k].tile, same, rows * cols, b.n);
        CHECK(same == rows * cols);
        free(out), free(b.p), free(v);
    }
}

TEST(refusals)
{
    int32_t *v = samples(32, 32, 12, false);
    struct buf b = encode(v, 32, 32, 12, false, 0);
    REQUIRE(b.p != NULL);
    uint16_t out[64 * 64];
    const struct {
        const char *what;
        struct j2k_frame f;
    } frames[] = {{"another size", {32, 33, 12, false}},
                  {"more bits than BitsStored", {32, 32, 10, false}}};
    for (size_t k = 0; k < sizeof frames / sizeof *frames; k++) {
        struct sf_err err = {0};
        CHECK(j2k_decode(b.p, b.n, &frames[k].f, out, "/parts/3", &err) == SF_EINVAL);
        CHECK(!strcmp(err.pointer, "/parts/3"));
        fprintf(stderr, "  %s: %s\n", frames[k].what, err.message);
    }
    struct j2k_frame f = {32, 32, 12, false};
    struct sf_err err = {0};
    CHECK(j2k_decode(b.p, b.n / 2, &f, out, "/parts/0", &err) == SF_EINVAL); /* truncated */
    fprintf(stderr, "  cut in half: %s\n", err.message);
    unsigned char *bad = malloc(b.n);
    memcpy(bad, b.p, b.n);
    for (size_t i = 60; i < b.n; i++) /* garbage after the main header's first markers */
        bad[i] = (unsigned char)(i * 151);
    memset(&err, 0, sizeof err);
    int rc = j2k_decode(bad, b.n, &f, out, "/parts/0", &err);
    CHECK(rc == 0 || rc == SF_EINVAL); /* (decodes to something, or refuses: never past out) */
    memcpy(bad, b.p, b.n); /* tiles of 1 x 1: 1024, under the cap; then of a claimed 65536 x 65536 image */
    bad[4 + 20] = bad[4 + 21] = bad[4 + 22] = 0, bad[4 + 23] = 1;
    bad[4 + 24] = bad[4 + 25] = bad[4 + 26] = 0, bad[4 + 27] = 1;
    struct j2k_frame big = {32, 32, 12, false};
    memset(&err, 0, sizeof err);
    rc = j2k_decode(bad, b.n, &big, out, "/parts/0", &err);
    CHECK(rc == 0 || rc == SF_EINVAL);
    bad[4 + 4] = 0, bad[4 + 5] = 1, bad[4 + 6] = 0, bad[4 + 7] = 0; /* Xsiz 65536 */
    bad[4 + 8] = 0, bad[4 + 9] = 1, bad[4 + 10] = 0, bad[4 + 11] = 0;
    struct j2k_frame huge = {65536, 65536, 12, false};
    memset(&err, 0, sizeof err);
    CHECK(j2k_decode(bad, b.n, &huge, out, "/parts/0", &err) == SF_EINVAL && strstr(err.message, "tiles"));
    fprintf(stderr, "  a claimed 65536 x 65536 image of 1 x 1 tiles: %s\n", err.message);
    memset(&err, 0, sizeof err);
    CHECK(j2k_decode("\xff\xd8\xff\xe0", 4, &f, out, "/parts/0", &err) == SF_EINVAL); /* a JPEG, not J2K */
    for (size_t n = 0; n < 45; n++) { /* every stream cut short of the SIZ marker's end */
        memset(&err, 0, sizeof err);
        CHECK(j2k_decode(b.p, n, &f, out, "/parts/0", &err) == SF_EINVAL);
    }
    memcpy(bad, b.p, b.n); /* tile sizes that wrap 32 bits: Xsiz 2^32 - 1, XTsiz 2^32 - 1 */
    memset(bad + 4 + 4, 0xff, 4), memset(bad + 4 + 20, 0xff, 4);
    struct j2k_frame wide = {32, -1, 12, false};
    memset(&err, 0, sizeof err);
    CHECK(j2k_decode(bad, b.n, &wide, out, "/parts/0", &err) == SF_EINVAL);
    struct j2k_frame sgn = {32, 32, 12, true}; /* an unsigned stream for a signed frame: read, its bits kept */
    memset(&err, 0, sizeof err);
    CHECK(j2k_decode(b.p, b.n, &sgn, out, "/parts/0", &err) == 0 && out[5] == (uint16_t)v[5]);
    free(bad), free(b.p), free(v);
}

int main(void)
{
    RUN(decodes_what_was_encoded);
    RUN(refusals);
    UNIT_END();
}
