/* test_png.c - PNG deflated by bands (api/png.h): read back chunk by chunk with zlib's own inflate
 * (which checks the stream and its Adler-32), the rows are the picture's, whatever the band height
 * and in whatever order the bands were deflated; every chunk's CRC holds; a band that failed fails
 * the join. */
#include "../../api/png.h"
#include "../unit.h"

#include <stdint.h>
#include <zlib.h>

static uint32_t be32(const unsigned char *p) { return (uint32_t)p[0] << 24 | (uint32_t)p[1] << 16 | (uint32_t)p[2] << 8 | p[3]; }

/* Walks the file's chunks (CRCs checked), inflates IDAT and compares the rows with rgb; the chunk
 * types in order into types (4 letters each). True when all holds. */
static bool read_back(const unsigned char *f, size_t len, const unsigned char *rgb, int W, int H, char *types)
{
    static const unsigned char SIG[8] = {137, 'P', 'N', 'G', 13, 10, 26, 10};
    if (len < 8 || memcmp(f, SIG, 8))
        return false;
    size_t raw_len = (size_t)(3 * W + 1) * H;
    unsigned char *raw = malloc(raw_len + 1);
    z_stream zs;
    memset(&zs, 0, sizeof zs);
    inflateInit(&zs);
    zs.next_out = raw, zs.avail_out = (uInt)raw_len + 1;
    bool ok = raw != NULL, ended = false;
    types[0] = 0;
    for (size_t p = 8; ok && p + 12 <= len;) {
        uint32_t n = be32(f + p);
        ok = p + 12 + n <= len && be32(f + p + 8 + n) == (uint32_t)crc32(crc32(0, Z_NULL, 0), f + p + 4, n + 4);
        strncat(types, (const char *)f + p + 4, 4);
        if (ok && !memcmp(f + p + 4, "IHDR", 4))
            ok = n == 13 && be32(f + p + 8) == (uint32_t)W && be32(f + p + 12) == (uint32_t)H && f[p + 16] == 8 && f[p + 17] == 2;
        if (ok && !memcmp(f + p + 4, "IDAT", 4)) {
            zs.next_in = (Bytef *)(f + p + 8), zs.avail_in = n;
            int z = inflate(&zs, Z_NO_FLUSH);
            ended = z == Z_STREAM_END;
            ok = z == Z_OK || ended;
        }
        p += 12 + n;
    }
    ok = ok && ended && zs.total_out == raw_len;
    for (int y = 0; ok && y < H; y++)
        ok = raw[(size_t)y * (3 * W + 1)] == 0 && !memcmp(raw + (size_t)y * (3 * W + 1) + 1, rgb + (size_t)y * 3 * W, 3 * (size_t)W);
    inflateEnd(&zs);
    free(raw);
    return ok;
}

/* A picture with runs and noise, so that deflate has both to do. */
static unsigned char *picture(int W, int H)
{
    unsigned char *rgb = malloc(3 * (size_t)W * H);
    uint32_t s = 12345;
    for (size_t k = 0; k < 3 * (size_t)W * H; k++) {
        s = s * 1664525u + 1013904223u;
        rgb[k] = (k / 3) % W < (size_t)W / 2 ? (unsigned char)(k % 3 * 80) : (unsigned char)(s >> 24);
    }
    return rgb;
}

TEST(bands_join_into_one_stream)
{
    const int sizes[][3] = {{1, 1, 16}, {5, 3, 1}, {64, 50, 16}, {333, 97, 16}, {1024, 40, 7}, {17, 200, 1000}};
    for (size_t c = 0; c < sizeof sizes / sizeof *sizes; c++) {
        const int W = sizes[c][0], H = sizes[c][1], rows = sizes[c][2];
        unsigned char *rgb = picture(W, H), *out = NULL, *whole = NULL;
        size_t len = 0, whole_len = 0;
        struct sf_err err = {0};
        struct png_bands *pb = png_bands_new(rgb, W, H, rows);
        REQUIRE(pb && png_bands_n(pb) == (H + rows - 1) / rows);
        for (int k = png_bands_n(pb) - 1; k >= 0; k--) /* any order: each band is its own stream */
            CHECK(png_band(pb, k) == 0);
        CHECK(png_join(pb, &out, &len, &err) == 0);
        char types[64];
        CHECK(out && read_back(out, len, rgb, W, H, types));
        CHECK_STR(types, "IHDRsRGBgAMAcHRMIDATIEND");
        CHECK(png_encode(rgb, W, H, &whole, &whole_len, &err) == 0); /* one band: the same rows */
        CHECK(whole && read_back(whole, whole_len, rgb, W, H, types));
        fprintf(stderr, "  %dx%d by %d rows: %zu bytes in %d bands, %zu in one\n", W, H, rows, len, png_bands_n(pb),
                whole_len);
        png_bands_free(pb);
        free(out), free(whole), free(rgb);
    }
}

/* A band never deflated is an error of the join, not a file with a hole. */
TEST(a_missing_band_fails_the_join)
{
    unsigned char *rgb = picture(8, 8), *out = NULL;
    size_t len = 0;
    struct sf_err err = {0};
    struct png_bands *pb = png_bands_new(rgb, 8, 8, 2);
    REQUIRE(pb);
    for (int k = 0; k < png_bands_n(pb); k += 2)
        png_band(pb, k);
    CHECK(png_join(pb, &out, &len, &err) != 0 && !out && len == 0 && strstr(err.message, "band 1"));
    CHECK(png_bands_new(rgb, 0, 8, 2) == NULL && png_bands_new(rgb, 8, 8, 0) == NULL);
    /* bands of 48 KB at least, 16 rows where rows are long */
    CHECK(png_band_rows(1024) == 16 && png_band_rows(4096) == 16 && png_band_rows(256) == 64);
    CHECK(png_band_rows(1) * 4 >= 48 * 1024 && png_band_rows(0) == png_band_rows(1));
    png_bands_free(pb);
    free(rgb);
}

int main(void)
{
    RUN(bands_join_into_one_stream);
    RUN(a_missing_band_fails_the_join);
    UNIT_END();
}
