/* j2k.h - a DICOM frame in JPEG 2000 (PS3.5 A.4.4: transfer syntaxes 1.2.840.10008.1.2.4.90 and .91)
 * or High-Throughput JPEG 2000 (A.4.11: .201 to .203), decoded by OpenJPEG: Debian's DCMTK has no
 * JPEG 2000 codec. One component of at most 16 bits, as the frame declares it: the codestream's
 * size, tiles, components and precision are read from its SIZ marker and checked against the
 * frame before OpenJPEG is given anything, so a stream cannot make it allocate past the frame. */
#ifndef SURFD_J2K_H
#define SURFD_J2K_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "../core/base/err.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Whether a transfer syntax UID is one of JPEG 2000's. */
bool j2k_syntax(const char *uid);

/* What the frame's data set declares. */
struct j2k_frame {
    int rows, cols;
    int bits_stored;  /* 1..16 */
    bool is_signed;   /* PixelRepresentation 1 */
};

/* Tiles a codestream may declare (OpenJPEG allocates a record for each as it reads the header). */
#define J2K_MAX_TILES 65536

/* Decodes the codestream data (len bytes, its fragments laid end to end) into out: rows x cols
 * samples row by row, as int16 (is_signed) or uint16. 0, or SF_EINVAL at where (a stream that is
 * not one component of the frame's size and at most its BitsStored bits, too many tiles, or one
 * that does not decode), SF_ENOMEM. The samples keep their bits: a stream coded unsigned for a
 * signed frame (as some writers do) is read by the frame's PixelRepresentation, as DCMTK's are. */
int j2k_decode(const void *data, size_t len, const struct j2k_frame *f, uint16_t *out, const char *where,
               struct sf_err *err);

#ifdef __cplusplus
}
#endif

#endif
