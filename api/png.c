/* png.c - PNG bytes deflated by bands (png.h). */
#include "png.h"

#include <stdbool.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <zlib.h>

#define PNG_LEVEL 2

struct band {
    unsigned char *bytes; /* its raw deflate stream */
    size_t len;
    uLong adler;          /* of its filtered rows */
    int rc;               /* 0, or why it failed; 1: not deflated yet */
};

struct png_bands {
    const unsigned char *rgb;
    int width, height, rows, n;
    struct band *band;
};

struct png_bands *png_bands_new(const unsigned char *rgb, int width, int height, int rows_per_band)
{
    if (width < 1 || height < 1 || rows_per_band < 1)
        return NULL;
    struct png_bands *pb = calloc(1, sizeof *pb);
    int n = (height + rows_per_band - 1) / rows_per_band;
    if (!pb || !(pb->band = calloc((size_t)n, sizeof *pb->band))) {
        free(pb);
        return NULL;
    }
    *pb = (struct png_bands){rgb, width, height, rows_per_band, n, pb->band};
    for (int k = 0; k < n; k++)
        pb->band[k].rc = 1;
    return pb;
}

int png_bands_n(const struct png_bands *pb) { return pb->n; }

int png_band_rows(int width)
{
    const int least = 48 * 1024, row = 3 * (width > 0 ? width : 1) + 1;
    return row * 16 >= least ? 16 : (least + row - 1) / row;
}

/* Feeds len bytes to the stream, growing b's buffer as the output needs. */
static int feed(z_stream *zs, struct band *b, size_t *cap, const unsigned char *in, size_t len, int flush)
{
    zs->next_in = (Bytef *)in; /* zlib's API is not const; it only reads */
    zs->avail_in = (uInt)len;
    for (;;) {
        if (zs->avail_out == 0) {
            size_t grown = 2 * *cap;
            unsigned char *p = realloc(b->bytes, grown);
            if (!p)
                return SF_ENOMEM;
            b->bytes = p;
            zs->next_out = p + *cap;
            zs->avail_out = (uInt)(grown - *cap);
            *cap = grown;
        }
        int z = deflate(zs, flush);
        if (z == Z_STREAM_ERROR)
            return SF_EBACKEND;
        if (zs->avail_in == 0 && zs->avail_out > 0 && (flush != Z_FINISH || z == Z_STREAM_END))
            return 0;
    }
}

/* Band k's rows [*y0, *y1), and the bytes they deflate (a filter byte a row). */
static size_t band_rows(const struct png_bands *pb, int k, int *y0, int *y1)
{
    *y0 = k * pb->rows, *y1 = *y0 + pb->rows < pb->height ? *y0 + pb->rows : pb->height;
    return (3 * (size_t)pb->width + 1) * (size_t)(*y1 - *y0);
}

int png_band(struct png_bands *pb, int k)
{
    struct band *b = &pb->band[k];
    int y0, y1;
    const size_t in = band_rows(pb, k, &y0, &y1);
    const size_t row = 3 * (size_t)pb->width;
    const bool last = k == pb->n - 1;
    static const unsigned char none = 0; /* each row's filter type */
    z_stream zs;
    memset(&zs, 0, sizeof zs);
    if (deflateInit2(&zs, PNG_LEVEL, Z_DEFLATED, -15, 8, Z_DEFAULT_STRATEGY) != Z_OK)
        return b->rc = SF_ENOMEM;
    size_t cap = deflateBound(&zs, (uLong)in) + 64;
    int rc = (b->bytes = malloc(cap)) ? 0 : SF_ENOMEM;
    zs.next_out = b->bytes;
    zs.avail_out = (uInt)cap;
    b->adler = adler32(0L, Z_NULL, 0);
    for (int y = y0; y < y1 && !rc; y++) {
        const unsigned char *r = pb->rgb + (size_t)y * row;
        b->adler = adler32(adler32(b->adler, &none, 1), r, (uInt)row);
        rc = feed(&zs, b, &cap, &none, 1, Z_NO_FLUSH);
        if (!rc)
            rc = feed(&zs, b, &cap, r, row, y + 1 < y1 ? Z_NO_FLUSH : last ? Z_FINISH : Z_SYNC_FLUSH);
    }
    b->len = cap - zs.avail_out;
    deflateEnd(&zs);
    return b->rc = rc;
}

static unsigned char *put32(unsigned char *p, uint32_t v)
{
    p[0] = (unsigned char)(v >> 24), p[1] = (unsigned char)(v >> 16), p[2] = (unsigned char)(v >> 8), p[3] = (unsigned char)v;
    return p + 4;
}

/* A chunk's length and type; its data follows, then put_crc. */
static unsigned char *chunk_head(unsigned char *p, uint32_t len, const char type[4])
{
    p = put32(p, len);
    memcpy(p, type, 4);
    return p + 4;
}

/* The CRC of the chunk whose type starts at t, its data ending at end. */
static unsigned char *put_crc(const unsigned char *t, unsigned char *end)
{
    return put32(end, (uint32_t)crc32(crc32(0L, Z_NULL, 0), t, (uInt)(end - t)));
}

int png_join(struct png_bands *pb, unsigned char **out, size_t *out_len, struct sf_err *err)
{
    *out = NULL;
    *out_len = 0;
    size_t data = 2 + 4; /* the zlib header and checksum about the bands' streams */
    uLong adler = adler32(0L, Z_NULL, 0);
    for (int k = 0, y0, y1; k < pb->n; k++) {
        if (pb->band[k].rc)
            return sf_fail(err, pb->band[k].rc < 0 ? pb->band[k].rc : SF_EBACKEND, "",
                           "the PNG's band %d could not be deflated", k);
        data += pb->band[k].len;
        adler = adler32_combine(adler, pb->band[k].adler, (z_off_t)band_rows(pb, k, &y0, &y1));
    }
    if (data > 0x7fffffffu)
        return sf_fail(err, SF_ELIMIT, "", "the PNG's data is over the 2 GB a chunk holds");
    static const unsigned char SIGNATURE[8] = {137, 'P', 'N', 'G', 13, 10, 26, 10};
    /* sRGB with the gAMA and cHRM that decoders unaware of it read instead (the PNG book's advice) */
    static const uint32_t CHRM[8] = {31270, 32900, 64000, 33000, 30000, 60000, 15000, 6000};
    size_t total = sizeof SIGNATURE + (12 + 13) + (12 + 1) + (12 + 4) + (12 + 32) + (12 + data) + 12;
    unsigned char *buf = malloc(total), *p = buf, *t;
    if (!buf)
        return sf_fail(err, SF_ENOMEM, "", "out of memory for the image");
    memcpy(p, SIGNATURE, sizeof SIGNATURE);
    p += sizeof SIGNATURE;
    t = p + 4, p = chunk_head(p, 13, "IHDR"); /* 8-bit RGB, deflate, adaptive filtering's set, no interlace */
    p = put32(put32(p, (uint32_t)pb->width), (uint32_t)pb->height);
    memcpy(p, (const unsigned char[5]){8, 2, 0, 0, 0}, 5);
    p = put_crc(t, p + 5);
    t = p + 4, p = chunk_head(p, 1, "sRGB"); /* the bands wrote sRGB; perceptual intent */
    *p++ = 0;
    p = put_crc(t, p);
    t = p + 4, p = chunk_head(p, 4, "gAMA");
    p = put_crc(t, put32(p, 45455));
    t = p + 4, p = chunk_head(p, 32, "cHRM");
    for (int k = 0; k < 8; k++)
        p = put32(p, CHRM[k]);
    p = put_crc(t, p);
    t = p + 4, p = chunk_head(p, (uint32_t)data, "IDAT");
    *p++ = 0x78, *p++ = 0x5e; /* deflate, 32 K window, "fast" level, (0x785e % 31 == 0) */
    for (int k = 0; k < pb->n; k++) {
        memcpy(p, pb->band[k].bytes, pb->band[k].len);
        p += pb->band[k].len;
    }
    p = put_crc(t, put32(p, (uint32_t)adler));
    t = p + 4, p = chunk_head(p, 0, "IEND");
    p = put_crc(t, p);
    *out = buf;
    *out_len = (size_t)(p - buf);
    return 0;
}

void png_bands_free(struct png_bands *pb)
{
    if (!pb)
        return;
    for (int k = 0; k < pb->n; k++)
        free(pb->band[k].bytes);
    free(pb->band);
    free(pb);
}

int png_encode(const unsigned char *rgb, int width, int height, unsigned char **out, size_t *out_len,
               struct sf_err *err)
{
    struct png_bands *pb = png_bands_new(rgb, width, height, height > 0 ? height : 1);
    if (!pb)
        return sf_fail(err, SF_ENOMEM, "", "out of memory for the image");
    png_band(pb, 0);
    int rc = png_join(pb, out, out_len, err);
    png_bands_free(pb);
    return rc;
}
