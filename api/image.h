/* image.h - a rendered frame as image-file bytes in memory (PNG 8-bit sRGB, EXR float32 with
 * depth and AOVs, TIFF 16-bit), through OpenImageIO behind image_oiio.cpp. Linking this pulls in
 * OpenImageIO (some 260 shared libraries, about half a second to start): only programs that
 * write images link it. The caller frees *out with free(). */
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
/* Loads OpenImageIO's writers now (a one-time cost of tens of milliseconds that the first
 * image_encode() would otherwise pay). Safe to call more than once. */
void image_init(void);

#ifdef __cplusplus
}
#endif

#endif
