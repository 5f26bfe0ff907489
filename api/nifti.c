/* nifti.c - NIfTI-1 and NIfTI-2 headers (nifti.h). The fields are read at nifti1.h's and
 * nifti2.h's offsets in the file's byte order (sizeof_hdr, 348 or 540, says which). */
#include "nifti.h"

#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <zlib.h>

/* A field of the header in its byte order. */
struct fields {
    const unsigned char *b;
    bool swap;
};

static uint64_t raw(const struct fields *f, size_t at, int n)
{
    uint64_t v = 0;
    for (int k = 0; k < n; k++)
        v |= (uint64_t)f->b[at + (f->swap ? n - 1 - k : k)] << (8 * k);
    return v;
}
static int64_t i16(const struct fields *f, size_t at) { return (int16_t)raw(f, at, 2); }
static int64_t i32(const struct fields *f, size_t at) { return (int32_t)raw(f, at, 4); }
static int64_t i64(const struct fields *f, size_t at) { return (int64_t)raw(f, at, 8); }
static double f32(const struct fields *f, size_t at)
{
    uint32_t u = (uint32_t)raw(f, at, 4);
    float x;
    memcpy(&x, &u, sizeof x);
    return x;
}
static double f64(const struct fields *f, size_t at)
{
    uint64_t u = raw(f, at, 8);
    double x;
    memcpy(&x, &u, sizeof x);
    return x;
}

/* The version sizeof_hdr names (0: none) and whether the file's order is the other one. */
static int version_of(const unsigned char *buf, size_t len, bool *swap)
{
    if (len < 348)
        return 0;
    for (int s = 0; s < 2; s++) {
        struct fields f = {buf, s == 1};
        int64_t n = i32(&f, 0);
        *swap = s == 1;
        if (n == 348 && (!memcmp(buf + 344, "n+1", 4) || !memcmp(buf + 344, "ni1", 4)))
            return 1;
        if (n == 540 && len >= 12 && (!memcmp(buf + 4, "n+2\0\r\n\032\n", 8) || !memcmp(buf + 4, "ni2\0\r\n\032\n", 8)))
            return 2;
    }
    return 0;
}

bool nifti_sniff(const unsigned char *buf, size_t len)
{
    bool swap;
    return version_of(buf, len, &swap) != 0;
}

int nifti_inflate_head(const char *src, size_t n, unsigned char *out, size_t cap, size_t *got, struct sf_err *err)
{
    z_stream z = {0};
    if (inflateInit2(&z, 15 + 32) != Z_OK) /* +32: gzip or zlib, by its magic */
        return sf_fail(err, SF_EBACKEND, "", "zlib would not start");
    z.next_in = (unsigned char *)(uintptr_t)src;
    z.avail_in = (unsigned)(n < (1u << 30) ? n : 1u << 30);
    z.next_out = out;
    z.avail_out = (unsigned)cap;
    int rc = Z_OK;
    while (rc == Z_OK && z.avail_out > 0)
        rc = inflate(&z, Z_NO_FLUSH);
    *got = (size_t)z.total_out;
    inflateEnd(&z);
    return rc == Z_OK || rc == Z_STREAM_END || (rc == Z_BUF_ERROR && *got > 0)
               ? 0
               : sf_fail(err, SF_EFORMAT, "header", "gzip data that does not inflate");
}

bool nifti_sniff_body(const char *body, size_t len)
{
    unsigned char head[NIFTI_HEADER_MAX];
    size_t got = 0;
    if (len >= 2 && (unsigned char)body[0] == 0x1f && (unsigned char)body[1] == 0x8b)
        return !nifti_inflate_head(body, len, head, sizeof head, &got, NULL) && nifti_sniff(head, got);
    return nifti_sniff((const unsigned char *)body, len);
}

/* The rotation of NIfTI's quaternion (b, c, d; a from the unit norm), nifti1.h's method 2. */
static void quaternion(double b, double c, double d, double r[3][3])
{
    double a = 1 - (b * b + c * c + d * d);
    a = a > 0 ? sqrt(a) : 0;
    double m[3][3] = {{a * a + b * b - c * c - d * d, 2 * (b * c - a * d), 2 * (b * d + a * c)},
                      {2 * (b * c + a * d), a * a + c * c - b * b - d * d, 2 * (c * d - a * b)},
                      {2 * (b * d - a * c), 2 * (c * d + a * b), a * a + d * d - c * c - b * b}};
    memcpy(r, m, sizeof m);
}

static int sample_bytes(int datatype)
{
    switch (datatype) {
    case 2: case 256: return 1;
    case 4: case 512: return 2;
    case 8: case 16: case 768: return 4;
    case 64: return 8;
    default: return 0;
    }
}

int nifti_header(const unsigned char *buf, size_t len, struct nifti_header *h, struct sf_err *err)
{
    memset(h, 0, sizeof *h);
    bool swap;
    int version = version_of(buf, len, &swap);
    if (!version)
        return sf_fail(err, SF_EFORMAT, "header", "not a NIfTI-1 or NIfTI-2 header (sizeof_hdr 348 or 540 and its magic)");
    const struct fields f = {buf, swap};
    bool pair = version == 1 ? buf[345] == 'i' : buf[5] == 'i';
    if (pair)
        return sf_fail(err, SF_EINVAL, "header", "a NIfTI header of a pair (.hdr and .img, magic ni%d): send the "
                       "single file (.nii or .nii.gz) its samples follow", version);
    if (version == 2 && len < 540)
        return sf_fail(err, SF_EFORMAT, "header", "a NIfTI-2 header is 540 bytes; the file has %zu", len);
    h->version = version;
    h->big_endian = swap; /* every host surfd is built for is little-endian */
    int64_t dim[8];
    double pixdim[8];
    for (int k = 0; k < 8; k++) {
        dim[k] = version == 1 ? i16(&f, 40 + 2 * (size_t)k) : i64(&f, 16 + 8 * (size_t)k);
        pixdim[k] = version == 1 ? f32(&f, 76 + 4 * (size_t)k) : f64(&f, 104 + 8 * (size_t)k);
    }
    h->datatype = (int)(version == 1 ? i16(&f, 70) : i16(&f, 12));
    double vox = version == 1 ? f32(&f, 108) : (double)i64(&f, 168);
    h->slope = version == 1 ? f32(&f, 112) : f64(&f, 176);
    h->inter = version == 1 ? f32(&f, 116) : f64(&f, 184);
    if (!isfinite(h->slope) || h->slope == 0) /* no scaling (nibabel writes NaN for none), whatever scl_inter is */
        h->slope = 0, h->inter = 0;
    int units = (version == 1 ? buf[123] : (int)i32(&f, 500)) & 7;
    int qform = (int)(version == 1 ? i16(&f, 252) : i32(&f, 344)), sform = (int)(version == 1 ? i16(&f, 254) : i32(&f, 348));
    if (dim[0] < 3 || dim[0] > 7)
        return sf_fail(err, SF_EINVAL, "header", "dim[0] is %lld: a volume has 3 dimensions", (long long)dim[0]);
    for (int k = 4; k <= dim[0]; k++)
        if (dim[k] != 1)
            return sf_fail(err, SF_EINVAL, "header", "dim[%d] is %lld: a series of volumes (4-D and over); one volume is "
                           "read", k, (long long)dim[k]);
    for (int a = 0; a < 3; a++)
        h->dims[a] = dim[a + 1];
    if (!(h->bytes = sample_bytes(h->datatype)))
        return sf_fail(err, SF_EINVAL, "header", "datatype %d: surfd reads NIfTI samples of uint8, int8, int16, uint16, "
                       "int32, uint32, float32 and float64 (codes 2, 256, 4, 512, 8, 768, 16, 64), not colours, complex "
                       "or 64-bit integers", h->datatype);
    int head = version == 1 ? 352 : 544;
    if (!(vox >= head && vox <= head + NIFTI_MAX_EXTENSIONS))
        return sf_fail(err, SF_EINVAL, "header", "vox_offset %g: a single file's samples follow its header (%d bytes) "
                       "and at most %d bytes of extensions", vox, head, NIFTI_MAX_EXTENSIONS);
    h->vox_offset = (int64_t)vox;
    if (!isfinite(h->inter))
        return sf_fail(err, SF_EINVAL, "header", "scl_inter is not a finite number");
    /* units: meters, mm, microns (0: unknown, taken as mm) */
    double unit = units == 1 ? 1000 : units == 3 ? 1e-3 : 1;
    if (sform > 0) {
        for (int r = 0; r < 3; r++)
            for (int c = 0; c < 4; c++)
                h->affine[r][c] = unit * (version == 1 ? f32(&f, 280 + 16 * (size_t)r + 4 * (size_t)c)
                                                      : f64(&f, 400 + 32 * (size_t)r + 8 * (size_t)c));
        h->xform = "sform";
    } else if (qform > 0) {
        double r[3][3], qfac = pixdim[0] < 0 ? -1 : 1;
        quaternion(version == 1 ? f32(&f, 256) : f64(&f, 352), version == 1 ? f32(&f, 260) : f64(&f, 360),
                   version == 1 ? f32(&f, 264) : f64(&f, 368), r);
        for (int i = 0; i < 3; i++) {
            for (int c = 0; c < 3; c++)
                h->affine[i][c] = unit * r[i][c] * pixdim[c + 1] * (c == 2 ? qfac : 1);
            h->affine[i][3] = unit * (version == 1 ? f32(&f, 268 + 4 * (size_t)i) : f64(&f, 376 + 8 * (size_t)i));
        }
        h->xform = "qform";
    } else { /* method 1: the pixdims alone, the first voxel at 0 */
        for (int a = 0; a < 3; a++)
            h->affine[a][a] = unit * pixdim[a + 1];
        h->xform = "pixdim";
    }
    for (int r = 0; r < 3; r++)
        for (int c = 0; c < 4; c++)
            if (!isfinite(h->affine[r][c]))
                return sf_fail(err, SF_EINVAL, "header", "the %s is not finite", h->xform);
    const unsigned char *in = buf + (version == 1 ? 328 : 508); /* intent_name[16], printable bytes up to a NUL */
    size_t n = 0;
    while (n < 16 && in[n] >= 0x20 && in[n] < 0x7f)
        n++;
    memcpy(h->intent_name, in, n);
    h->intent_name[n] = 0;
    return 0;
}

/* ---- the label table of an extension ---- */

/* The text at s (to end), an XML attribute's or element's: the five entities read, blanks at
 * either end dropped, into out (cap bytes, NUL-terminated). */
static size_t xml_text(const char *s, const char *end, char *out, size_t cap)
{
    static const struct { const char *name; char c; } ENT[] = {{"&amp;", '&'}, {"&lt;", '<'}, {"&gt;", '>'},
                                                               {"&quot;", '"'}, {"&apos;", '\''}};
    size_t n = 0;
    while (s < end && (*s == ' ' || *s == '\t' || *s == '\r' || *s == '\n'))
        s++;
    while (s < end && n + 1 < cap) {
        char c = *s++;
        for (size_t k = 0; c == '&' && k < sizeof ENT / sizeof *ENT; k++) {
            size_t l = strlen(ENT[k].name);
            if ((size_t)(end - (s - 1)) >= l && !memcmp(s - 1, ENT[k].name, l)) {
                c = ENT[k].c;
                s += l - 1;
                break;
            }
        }
        out[n++] = c;
    }
    while (n && (out[n - 1] == ' ' || out[n - 1] == '\t' || out[n - 1] == '\r' || out[n - 1] == '\n'))
        n--;
    out[n] = 0;
    return n;
}

static const char *find(const char *s, const char *end, const char *what)
{
    size_t n = strlen(what);
    for (; s && end - s >= (ptrdiff_t)n; s++)
        if (*s == *what && !memcmp(s, what, n))
            return s;
    return NULL;
}

/* The <Label Key="N">name</Label> elements of text [s, end). */
static int label_elements(const char *s, const char *end, void (*fn)(void *, long long, const char *, size_t), void *ctx)
{
    int found = 0;
    for (const char *at = find(s, end, "<Label"); at && end - at > 6; at = find(at + 1, end, "<Label")) {
        const char *close = find(at, end, ">"), *key = find(at, close, "Key=");
        if (!close || !key || (at[6] != ' ' && at[6] != '\t' && at[6] != '\n' && at[6] != '\r'))
            continue; /* <LabelTable>, or no key */
        key += 4;
        char quote = key < close ? *key : 0, digits[24];
        if (quote != '"' && quote != '\'')
            continue;
        const char *kend = memchr(key + 1, quote, (size_t)(close - key - 1));
        if (!kend || xml_text(key + 1, kend, digits, sizeof digits) == 0)
            continue;
        char *stop;
        long long value = strtoll(digits, &stop, 10);
        const char *text = close + 1, *tend = find(text, end, "</Label>");
        if (*stop || !tend || close[-1] == '/')
            continue;
        const char *cdata = find(text, tend, "<![CDATA[");
        if (cdata) {
            const char *cend = find(cdata, tend, "]]>");
            if (!cend)
                continue;
            text = cdata + 9, tend = cend;
            fn(ctx, value, text, (size_t)(tend - text));
        } else {
            char name[256];
            size_t n = xml_text(text, tend, name, sizeof name);
            fn(ctx, value, name, n);
        }
        found++;
    }
    return found;
}

int nifti_label_table(const unsigned char *file, size_t len, const struct nifti_header *h,
                      void (*fn)(void *ctx, long long value, const char *name, size_t n), void *ctx)
{
    size_t at = h->version == 1 ? 348 : 540, stop = (size_t)h->vox_offset < len ? (size_t)h->vox_offset : len;
    if (at + 4 > stop || file[at] == 0) /* the extender: no extensions */
        return 0;
    const struct fields f = {file, h->big_endian};
    int found = 0;
    for (at += 4; at + 8 <= stop;) {
        int64_t esize = i32(&f, at);
        if (esize < 8 || (uint64_t)esize > stop - at)
            break;
        found += label_elements((const char *)file + at + 8, (const char *)file + at + (size_t)esize, fn, ctx);
        at += (size_t)esize;
    }
    return found;
}
