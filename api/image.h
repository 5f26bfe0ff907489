/* image.h - a rendered frame as image-file bytes in memory (PNG 8-bit sRGB, EXR float32 with
 * depth and AOVs, TIFF 16-bit), through OpenImageIO behind image_oiio.cpp; PNG from the 8-bit
 * picture (srgb8_only) by png.h, without it.
 *
 * OpenImageIO as Debian builds it pulls in some 260 shared libraries (openvdb, gdal, opencv,
 * poppler...) holding 70-90 MB of a process's resident memory, which a node that only extracts
 * isosurfaces or measures volumes never uses. So the shim is its own shared object,
 * libsurfd-image.so, loaded by image.c with dlopen() on the first image (or image_init()):
 * found next to the executable, then in ../lib/surfd/ beside its bin/ (the installed layout).
 * The caller of image_encode() frees *out with free(). */
#ifndef SURFD_IMAGE_H
#define SURFD_IMAGE_H

#include <stddef.h>

#ifdef __cplusplus
extern "C" { /* the C headers below declare C functions */
#endif

#include "../core/base/err.h"
#include "../core/trace/render.h"
#include "scene_io.h"

int image_encode(const struct frame_image *img, enum image_format fmt, unsigned char **out, size_t *out_len,
                 struct sf_err *err);
/* Loads the library and OpenImageIO's writers now (a one-time cost that the first
 * image_encode() would otherwise pay): 0, or -1 with why. Safe to call more than once, from
 * any thread. */
int image_init(struct sf_err *err);
/* Finds the library without loading it (a server checks at start what it will need later):
 * 0, or -1 naming the places looked in. */
int image_locate(struct sf_err *err);

/* The library's entry points, the same contracts as image_init() and image_encode(); only
 * image.c calls them. */
void image_oiio_init(void);
int image_oiio_encode(const struct frame_image *img, enum image_format fmt, unsigned char **out, size_t *out_len,
                      struct sf_err *err);

#ifdef __cplusplus
}
#endif

#endif
