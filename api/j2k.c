/* j2k.c - JPEG 2000 frames through OpenJPEG (j2k.h). The codestream's main header is read here
 * first (ISO/IEC 15444-1 A.5.1, the SIZ marker right after SOC) for what it claims; OpenJPEG then
 * decodes from memory through its stream callbacks, one thread, its messages dropped (api/ logs
 * nothing). */
#include "j2k.h"

#include <openjpeg.h>
#include <string.h>

static const char *const SYNTAXES[] = {"1.2.840.10008.1.2.4.90", "1.2.840.10008.1.2.4.91", "1.2.840.10008.1.2.4.201",
                                       "1.2.840.10008.1.2.4.202", "1.2.840.10008.1.2.4.203"};

bool j2k_syntax(const char *uid)
{
    for (size_t k = 0; uid && k < sizeof SYNTAXES / sizeof *SYNTAXES; k++)
        if (!strcmp(uid, SYNTAXES[k]))
            return true;
    return false;
}

static uint32_t be32(const unsigned char *p) { return (uint32_t)p[0] << 24 | (uint32_t)p[1] << 16 | (uint32_t)p[2] << 8 | p[3]; }

/* The SIZ marker against the frame: 0 or SF_EINVAL. */
static int check_siz(const unsigned char *b, size_t len, const struct j2k_frame *f, const char *where,
                     struct sf_err *err)
{
    if (len < 4 + 38 + 3 || b[0] != 0xff || b[1] != 0x4f || b[2] != 0xff || b[3] != 0x51)
        return sf_fail(err, SF_EINVAL, where, "the frame is no JPEG 2000 codestream (no SOC and SIZ markers)");
    const unsigned char *s = b + 4; /* Lsiz Rsiz Xsiz Ysiz XOsiz YOsiz XTsiz YTsiz XTOsiz YTOsiz Csiz Ssiz... */
    uint32_t x = be32(s + 4), y = be32(s + 8), x0 = be32(s + 12), y0 = be32(s + 16), tx = be32(s + 20);
    uint32_t ty = be32(s + 24), tx0 = be32(s + 28), ty0 = be32(s + 32);
    unsigned comps = (unsigned)s[36] << 8 | s[37], ssiz = s[38], prec = (ssiz & 0x7f) + 1, xr = s[39], yr = s[40];
    if (x <= x0 || y <= y0 || x - x0 != (uint32_t)f->cols || y - y0 != (uint32_t)f->rows)
        return sf_fail(err, SF_EINVAL, where, "the JPEG 2000 image is %u x %u, not the frame's %d x %d (Columns x Rows)",
                       x > x0 ? x - x0 : 0, y > y0 ? y - y0 : 0, f->cols, f->rows);
    if (comps != 1 || xr != 1 || yr != 1)
        return sf_fail(err, SF_EINVAL, where, "the JPEG 2000 image has %u components (or subsampled ones): a frame is one", comps);
    if ((int)prec > f->bits_stored) /* (its sign may differ: the frame's PixelRepresentation reads the bits) */
        return sf_fail(err, SF_EINVAL, where, "the JPEG 2000 samples are %u bits, more than the frame's %d (BitsStored)",
                       prec, f->bits_stored);
    if (!tx || !ty || tx0 > x0 || ty0 > y0)
        return sf_fail(err, SF_EINVAL, where, "the JPEG 2000 tiles are not laid over the image");
    uint64_t tiles = (((uint64_t)x - tx0 + tx - 1) / tx) * (((uint64_t)y - ty0 + ty - 1) / ty);
    if (tiles > J2K_MAX_TILES)
        return sf_fail(err, SF_EINVAL, where, "the JPEG 2000 image claims %llu tiles, over the limit of %d",
                       (unsigned long long)tiles, J2K_MAX_TILES);
    return 0;
}

/* ---- OpenJPEG reading from memory ---- */

struct mem {
    const unsigned char *p;
    size_t n, at;
};

static OPJ_SIZE_T mem_read(void *buf, OPJ_SIZE_T n, void *user)
{
    struct mem *m = user;
    if (m->at >= m->n)
        return (OPJ_SIZE_T)-1;
    size_t k = n < m->n - m->at ? n : m->n - m->at;
    memcpy(buf, m->p + m->at, k);
    m->at += k;
    return k;
}

static OPJ_OFF_T mem_skip(OPJ_OFF_T n, void *user)
{
    struct mem *m = user;
    if (n < 0 || (size_t)n > m->n - m->at)
        return -1;
    m->at += (size_t)n;
    return n;
}

static OPJ_BOOL mem_seek(OPJ_OFF_T n, void *user)
{
    struct mem *m = user;
    if (n < 0 || (size_t)n > m->n)
        return OPJ_FALSE;
    m->at = (size_t)n;
    return OPJ_TRUE;
}

static void quiet(const char *msg, void *user)
{
    (void)msg, (void)user;
}

int j2k_decode(const void *data, size_t len, const struct j2k_frame *f, uint16_t *out, const char *where,
               struct sf_err *err)
{
    int rc = check_siz(data, len, f, where, err);
    if (rc)
        return rc;
    struct mem m = {data, len, 0};
    opj_codec_t *codec = opj_create_decompress(OPJ_CODEC_J2K);
    opj_stream_t *s = opj_stream_create(1 << 16, OPJ_TRUE);
    opj_image_t *img = NULL;
    opj_dparameters_t par;
    opj_set_default_decoder_parameters(&par);
    if (!codec || !s) {
        rc = sf_fail(err, SF_ENOMEM, where, "out of memory for a JPEG 2000 decoder");
        goto done;
    }
    opj_set_info_handler(codec, quiet, NULL), opj_set_warning_handler(codec, quiet, NULL);
    opj_set_error_handler(codec, quiet, NULL);
    opj_stream_set_user_data(s, &m, NULL);
    opj_stream_set_user_data_length(s, len);
    opj_stream_set_read_function(s, mem_read);
    opj_stream_set_skip_function(s, mem_skip);
    opj_stream_set_seek_function(s, mem_seek);
    if (!opj_setup_decoder(codec, &par) || !opj_read_header(s, codec, &img) || !opj_decode(codec, s, img) ||
        !opj_end_decompress(codec, s)) {
        rc = sf_fail(err, SF_EINVAL, where, "the JPEG 2000 codestream does not decode");
        goto done;
    }
    const opj_image_comp_t *c = &img->comps[0];
    if (img->numcomps != 1 || !c->data || c->w != (OPJ_UINT32)f->cols || c->h != (OPJ_UINT32)f->rows) {
        rc = sf_fail(err, SF_EINVAL, where, "the JPEG 2000 codestream decodes to another image than its header said");
        goto done;
    }
    const int bits = (int)c->prec < f->bits_stored ? (int)c->prec : f->bits_stored; /* (the stream's own sign) */
    const int32_t lo = c->sgnd ? -(1 << (bits - 1)) : 0;
    const int32_t hi = c->sgnd ? (1 << (bits - 1)) - 1 : (int32_t)((1u << bits) - 1);
    for (size_t i = 0, n = (size_t)f->rows * (size_t)f->cols; i < n; i++) {
        int32_t v = c->data[i];
        v = v < lo ? lo : v > hi ? hi : v; /* (within what its bits hold, as a conformant stream is) */
        out[i] = (uint16_t)v;
    }
done:
    if (img)
        opj_image_destroy(img);
    if (s)
        opj_stream_destroy(s);
    if (codec)
        opj_destroy_codec(codec);
    return rc;
}
