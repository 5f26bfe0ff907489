/* png.h - an 8-bit RGB picture as PNG bytes, deflated band by band so that the bands go on any
 * threads at once (the render job's last phase, the CLI's threads).
 *
 *   png_bands_new()  the picture's bands of rows_per_band rows
 *   png_band()       deflates band k (distinct bands on any threads at once)
 *   png_join()       after every band: the file (IHDR, sRGB with gAMA and cHRM, one IDAT, IEND)
 *
 * Each band is its own raw deflate stream ended on a byte boundary (a sync flush; the last band's
 * ends the stream), so the bands' streams laid end to end are one, as pigz joins its blocks; the
 * zlib checksum is the bands' Adler-32s combined. Rows carry filter type 0 (none) and zlib level 2
 * (api/image_oiio.cpp measured the filters and levels: the adaptive filter search costs 4x the
 * deflate for 15 % smaller files). Written by hand over zlib because no PNG library deflates a
 * picture's parts in parallel: through OpenImageIO and libpng the heart model's 1024² picture took
 * 8.4 ms on one thread after a 67 ms render on two. */
#ifndef SURFD_PNG_H
#define SURFD_PNG_H

#include <stddef.h>

#include "../core/base/err.h"

struct png_bands;

/* Rows a band for a picture width pixels wide, as the callers take them: 16 (a 1024-wide band
 * deflates in 0.12 ms), more where rows are short, so that a band holds 48 KB at least (its
 * deflate state, some 270 KB, is made afresh for each). */
int png_band_rows(int width);

/* NULL when out of memory. rgb (width * height * 3 bytes, rows top first) is borrowed until
 * png_join. */
struct png_bands *png_bands_new(const unsigned char *rgb, int width, int height, int rows_per_band);
int png_bands_n(const struct png_bands *pb);
/* 0, or SF_ENOMEM / SF_EBACKEND (png_join then fails with it). */
int png_band(struct png_bands *pb, int k);
/* The file's bytes (*out freed by the caller): 0, or an SF_E* code with err filled. */
int png_join(struct png_bands *pb, unsigned char **out, size_t *out_len, struct sf_err *err);
void png_bands_free(struct png_bands *pb);

/* The whole picture on the calling thread. */
int png_encode(const unsigned char *rgb, int width, int height, unsigned char **out, size_t *out_len,
               struct sf_err *err);

#endif
