/* fuzz_j2k.c - a JPEG 2000 codestream (api/j2k.h) decoded as a DICOM frame of the size its SIZ
 * marker says (up to 256 x 256, 12 or 16 bits, signed by its own flag): whatever the stream, the
 * decoder answers 0 or SF_EINVAL and writes no sample past the frame, and never asks OpenJPEG to
 * read a header that claims more tiles than J2K_MAX_TILES. */
#include "../../api/j2k.h"
#include "fuzz.h"

static uint32_t be32(const uint8_t *p) { return (uint32_t)p[0] << 24 | (uint32_t)p[1] << 16 | (uint32_t)p[2] << 8 | p[3]; }

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 4 + 41)
        return 0;
    uint32_t x = be32(data + 8), y = be32(data + 12), x0 = be32(data + 16), y0 = be32(data + 20);
    if (x <= x0 || y <= y0 || x - x0 > 256 || y - y0 > 256)
        return 0;
    struct j2k_frame f = {(int)(y - y0), (int)(x - x0), (data[42] & 0x7f) + 1 > 12 ? 16 : 12, (data[42] & 0x80) != 0};
    size_t n = (size_t)f.rows * (size_t)f.cols;
    uint16_t *out = malloc(sizeof *out * n);
    if (!out)
        return 0;
    struct sf_err err = {0};
    int rc = j2k_decode(data, size, &f, out, "/parts/0", &err);
    if (rc != 0 && rc != SF_EINVAL && rc != SF_ENOMEM)
        abort();
    free(out);
    return 0;
}
