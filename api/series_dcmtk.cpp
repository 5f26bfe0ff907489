// series_dcmtk.cpp - a DICOM CT/MR series to one sample grid (dicom_series.h), with DCMTK as the
// RT Structure Set reader uses it. Uncompressed transfer syntaxes, and the compressed ones a PACS
// sends that Debian's DCMTK decodes: RLE (dcmdata), JPEG baseline, extended and lossless (dcmjpeg),
// JPEG-LS (dcmjpls); JPEG 2000, for which it has no codec, is refused by name. A slice is decoded
// on the worker that reads the series (the check on the HTTP side reads its header alone), into
// Rows x Columns samples its header declared and the series' size was checked against.
#include "dcmtk_in.h"
#include "dicom_series.h"
#include "ranges.h"

#include <dcmtk/config/osconfig.h>
#include <dcmtk/dcmdata/dcistrmb.h>
#include <dcmtk/dcmdata/dcrledrg.h>
#include <dcmtk/dcmdata/dctk.h>
#include <dcmtk/dcmjpeg/djdecode.h>
#include <dcmtk/dcmjpls/djdecode.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <new>
#include <vector>

namespace {

/* The ranges a slice's geometry and rescale must keep, so that every product the grid and the
 * mesh make of them (positions over spacings, samples times slopes) stays finite in float, and
 * a volume comes out of real numbers: positions within RANGE_MAX_COORD, PixelSpacing and the
 * spacing between slices within [RANGE_MIN_SPACING, RANGE_MAX_SPACING] (ranges.h, as every
 * volume's); a 16-bit sample times 1e6 plus 1e9 is well inside float. */
#define SERIES_MAX_SLOPE 1e6     /* |RescaleSlope| */
#define SERIES_MAX_INTERCEPT 1e9 /* |RescaleIntercept| */
#define ORIENT_EPS 1e-3          /* how far past 1 a direction cosine may round */

struct slice {
    int part;
    double pos[3], orient[6], spacing[2], slope = 1, intercept = 0, s = 0;
    unsigned rows = 0, cols = 0, bits = 0, stored = 0;
    bool is_signed = false;
    std::vector<uint16_t> pixels; // 8-bit samples widened
};

int fail_part(struct sf_err *err, int code, int part, const char *fmt, const char *what)
{
    char where[32];
    snprintf(where, sizeof where, "/parts/%d", part);
    return sf_fail(err, code, where, fmt, what);
}

enum { GOT, MISSING, NOT_FINITE };

/* The first n values of tag: GOT, MISSING (absent or fewer than n) or NOT_FINITE. */
int get_doubles(DcmDataset *ds, const DcmTagKey &tag, double *out, unsigned n)
{
    for (unsigned k = 0; k < n; k++) {
        Float64 v;
        if (ds->findAndGetFloat64(tag, v, k).bad())
            return MISSING;
        if (!std::isfinite(v))
            return NOT_FINITE;
        out[k] = v;
    }
    return GOT;
}

/* 0 when each of the n values of name (read as got says) is within [lo, hi] in magnitude; else
 * SF_EINVAL naming the element and its values. missing_ok: an absent element keeps the default. */
int check_range(struct sf_err *err, int part, const char *name, int got, const double *v, unsigned n, double lo,
                double hi, bool missing_ok)
{
    char what[240];
    if (got == MISSING && missing_ok)
        return 0;
    if (got == MISSING) {
        snprintf(what, sizeof what, "%s is missing or has fewer than %u values", name, n);
        return fail_part(err, SF_EINVAL, part, "%s", what);
    }
    if (got == NOT_FINITE) {
        snprintf(what, sizeof what, "%s holds a value that is not a finite number", name);
        return fail_part(err, SF_EINVAL, part, "%s", what);
    }
    for (unsigned k = 0; k < n; k++)
        if (!(std::fabs(v[k]) >= lo && std::fabs(v[k]) <= hi)) {
            if (lo > 0)
                snprintf(what, sizeof what, "%s value %u is %.6g: surfd reads %g to %g in magnitude", name, k + 1,
                         v[k], lo, hi);
            else
                snprintf(what, sizeof what, "%s value %u is %.6g: surfd reads at most %g in magnitude", name, k + 1,
                         v[k], hi);
            return fail_part(err, SF_EINVAL, part, "%s", what);
        }
    return 0;
}

/* The decoders, registered once a process (DCMTK's registries are global). */
void register_codecs()
{
    static std::once_flag once;
    std::call_once(once, [] {
        DcmRLEDecoderRegistration::registerCodecs();
        DJDecoderRegistration::registerCodecs();
        DJLSDecoderRegistration::registerCodecs();
    });
}

/* Whether a compressed transfer syntax is one those decoders take. */
bool decodable(E_TransferSyntax t)
{
    switch (t) {
    case EXS_RLELossless:
    case EXS_JPEGProcess1:
    case EXS_JPEGProcess2_4:
    case EXS_JPEGProcess14:
    case EXS_JPEGProcess14SV1:
    case EXS_JPEGLSLossless:
    case EXS_JPEGLSLossy:
        return true;
    default:
        return false;
    }
}

int read_slice(const struct part &p, int k, bool check_only, slice &sl, struct sf_err *err)
{
    char where[32];
    snprintf(where, sizeof where, "/parts/%d", k);
    DcmFileFormat ff;
    int rc = dcm_read_object(p.data, p.len, where, check_only ? 4096 : DCM_MaxReadLength, ff, err);
    if (rc)
        return rc;
    DcmDataset *ds = ff.getDataset();
    E_TransferSyntax xfer = ds->getOriginalXfer();
    DcmXfer x(xfer);
    if (x.isEncapsulated() && !decodable(xfer))
        return fail_part(err, SF_EINVAL, k, "compressed pixel data (%s) is not read: send the series uncompressed, or "
                         "as RLE, JPEG (baseline, extended, lossless) or JPEG-LS", x.getXferName());
    Uint16 rows = 0, cols = 0, bits = 0, stored = 0, rep = 0, spp = 1;
    if (ds->findAndGetUint16(DCM_Rows, rows).bad() || ds->findAndGetUint16(DCM_Columns, cols).bad() || rows < 1 ||
        cols < 1)
        return fail_part(err, SF_EINVAL, k, "%s", "an image part without Rows and Columns (is it an image?)");
    ds->findAndGetUint16(DCM_BitsAllocated, bits);
    ds->findAndGetUint16(DCM_BitsStored, stored);
    ds->findAndGetUint16(DCM_PixelRepresentation, rep);
    ds->findAndGetUint16(DCM_SamplesPerPixel, spp);
    if ((bits != 8 && bits != 16) || spp != 1)
        return fail_part(err, SF_EINVAL, k, "%s", "samples are one channel of 8 or 16 bits (a CT or MR image)");
    /* one frame a part, of less than 2 GB: DCMTK 3.6.7's decoders size their buffer as a frame
     * times NumberOfFrames in 32 bits, which a crafted header makes wrap (upstream 31ff413f9) */
    Sint32 frames = 1;
    if (ds->findAndGetSint32(DCM_NumberOfFrames, frames).good() && frames != 1)
        return fail_part(err, SF_EINVAL, k, "%s", "a multi-frame image (NumberOfFrames over 1): a series is read one "
                         "image a part");
    if ((uint64_t)rows * cols * (bits / 8) >= (1ull << 31))
        return fail_part(err, SF_ELIMIT, k, "%s", "an image of 2 GB or more (Rows x Columns x BitsAllocated)");
    /* ImagePositionPatient: the slice's corner; ImageOrientationPatient: two direction cosines */
    if ((rc = check_range(err, k, "ImagePositionPatient (mm)", get_doubles(ds, DCM_ImagePositionPatient, sl.pos, 3),
                          sl.pos, 3, 0, RANGE_MAX_COORD, false)) ||
        (rc = check_range(err, k, "ImageOrientationPatient", get_doubles(ds, DCM_ImageOrientationPatient, sl.orient, 6),
                          sl.orient, 6, 0, 1 + ORIENT_EPS, false)) ||
        (rc = check_range(err, k, "PixelSpacing (mm)", get_doubles(ds, DCM_PixelSpacing, sl.spacing, 2), sl.spacing, 2,
                          RANGE_MIN_SPACING, RANGE_MAX_SPACING, false)))
        return rc;
    if (!(sl.spacing[0] > 0) || !(sl.spacing[1] > 0))
        return fail_part(err, SF_EINVAL, k, "%s", "PixelSpacing is not positive");
    if ((rc = check_range(err, k, "RescaleSlope", get_doubles(ds, DCM_RescaleSlope, &sl.slope, 1), &sl.slope, 1, 0,
                          SERIES_MAX_SLOPE, true)) ||
        (rc = check_range(err, k, "RescaleIntercept", get_doubles(ds, DCM_RescaleIntercept, &sl.intercept, 1),
                          &sl.intercept, 1, 0, SERIES_MAX_INTERCEPT, true)))
        return rc;
    if (sl.slope == 0)
        return fail_part(err, SF_EINVAL, k, "%s", "RescaleSlope is 0");
    sl.part = k, sl.rows = rows, sl.cols = cols, sl.bits = bits, sl.stored = stored ? stored : bits;
    sl.is_signed = rep == 1;
    if (check_only)
        return 0;
    if (x.isEncapsulated()) { /* decoded in place, to the samples Rows x Columns declare */
        register_codecs();
        OFCondition c = ds->chooseRepresentation(EXS_LittleEndianExplicit, nullptr);
        if (c.bad() || !ds->canWriteXfer(EXS_LittleEndianExplicit))
            return fail_part(err, SF_EINVAL, k, "the compressed pixel data does not decode: %s",
                             c.bad() ? c.text() : "its frames do not make the image");
        /* the decoder writes what the stream held: samples of another width than the header said
         * are refused, a narrower precision taken */
        Uint16 now_bits = 0, now_spp = 1, now_stored = 0;
        ds->findAndGetUint16(DCM_BitsAllocated, now_bits);
        ds->findAndGetUint16(DCM_SamplesPerPixel, now_spp);
        if (now_bits != bits || now_spp != spp)
            return fail_part(err, SF_EINVAL, k, "%s", "the compressed samples are not of the width the header says "
                             "(BitsAllocated, SamplesPerPixel)");
        if (ds->findAndGetUint16(DCM_BitsStored, now_stored).good() && now_stored > 0 && now_stored <= bits)
            sl.stored = now_stored;
    }
    size_t n = (size_t)rows * cols;
    if (bits == 16) {
        const Uint16 *px = nullptr;
        unsigned long count = 0;
        if (ds->findAndGetUint16Array(DCM_PixelData, px, &count).bad() || !px || count < n)
            return fail_part(err, SF_EINVAL, k, "%s", "the pixel data is missing or shorter than Rows x Columns");
        sl.pixels.assign(px, px + n);
    } else {
        const Uint8 *px = nullptr;
        unsigned long count = 0;
        if (ds->findAndGetUint8Array(DCM_PixelData, px, &count).bad() || !px || count < n)
            return fail_part(err, SF_EINVAL, k, "%s", "the pixel data is missing or shorter than Rows x Columns");
        sl.pixels.assign(px, px + n);
    }
    return 0;
}

/* A sample's value: its BitsStored low bits, two's complement when signed (the bits above them
 * are not the sign: writers and decoders leave them as they are). */
double stored_value(const slice &sl, uint16_t raw)
{
    unsigned bits = sl.stored >= sl.bits || sl.stored == 0 ? sl.bits : sl.stored;
    uint32_t v = raw & (bits >= 16 ? 0xffffu : (1u << bits) - 1);
    if (sl.is_signed && (v >> (bits - 1)) & 1)
        return (double)v - (double)(1u << bits);
    return (double)v;
}

} // namespace

static int read_series(const struct part *parts, int n, bool check_only, size_t max_samples, struct series *out,
                       struct sf_err *err);

extern "C" int series_read(const struct part *parts, int n, bool check_only, size_t max_samples, struct series *out,
                           struct sf_err *err)
{
    memset(out, 0, sizeof *out);
    try { /* what C++ allocates here, DCMTK's buffers and the slices', may throw: never past C */
        return read_series(parts, n, check_only, max_samples, out, err);
    } catch (const std::bad_alloc &) {
        free(out->owned);
        memset(out, 0, sizeof *out);
        return sf_fail(err, SF_ENOMEM, "/parts", "out of memory for the series");
    }
}

static int read_series(const struct part *parts, int n, bool check_only, size_t max_samples, struct series *out,
                       struct sf_err *err)
{
    if (n < 2)
        return sf_fail(err, SF_EINVAL, "/parts", "a series is at least 2 slices (one DICOM image a part)");
    std::vector<slice> sl((size_t)n);
    for (int k = 0; k < n; k++) {
        int rc = read_slice(parts[k], k, check_only, sl[(size_t)k], err);
        if (rc)
            return rc;
    }
    const slice &a = sl[0];
    if ((size_t)a.rows * a.cols * (size_t)n > max_samples)
        return sf_fail(err, SF_ELIMIT, "/parts", "the series has over %zu samples", max_samples);
    double r[3] = {a.orient[0], a.orient[1], a.orient[2]}, c[3] = {a.orient[3], a.orient[4], a.orient[5]};
    double nrm[3] = {r[1] * c[2] - r[2] * c[1], r[2] * c[0] - r[0] * c[2], r[0] * c[1] - r[1] * c[0]};
    double len = std::sqrt(nrm[0] * nrm[0] + nrm[1] * nrm[1] + nrm[2] * nrm[2]);
    if (!(len > 0.99 && len < 1.01))
        return fail_part(err, SF_EINVAL, 0, "%s", "ImageOrientationPatient is not two unit, perpendicular directions");
    for (slice &s : sl) {
        if (s.rows != a.rows || s.cols != a.cols || s.bits != a.bits)
            return fail_part(err, SF_EINVAL, s.part, "%s", "a slice of another size than the first part's");
        for (int i = 0; i < 6; i++)
            if (std::fabs(s.orient[i] - a.orient[i]) > 1e-4)
                return fail_part(err, SF_EINVAL, s.part, "%s", "a slice of another orientation than the first part's");
        for (int i = 0; i < 2; i++)
            if (std::fabs(s.spacing[i] - a.spacing[i]) > 1e-4 * a.spacing[i])
                return fail_part(err, SF_EINVAL, s.part, "%s", "a slice of another PixelSpacing than the first part's");
        s.s = (s.pos[0] * nrm[0] + s.pos[1] * nrm[1] + s.pos[2] * nrm[2]) / len;
    }
    std::sort(sl.begin(), sl.end(), [](const slice &x, const slice &y) { return x.s < y.s; });
    double mean = (sl.back().s - sl.front().s) / (n - 1);
    if (!(mean > 0))
        return fail_part(err, SF_EINVAL, sl[1].part, "%s", "two slices at the same position");
    if (mean < RANGE_MIN_SPACING || mean > RANGE_MAX_SPACING) {
        char what[200];
        snprintf(what, sizeof what, "ImagePositionPatient puts the slices %.3g mm apart on average: surfd reads %g to "
                 "%g mm", mean, RANGE_MIN_SPACING, RANGE_MAX_SPACING);
        return fail_part(err, SF_EINVAL, sl[(size_t)n - 1].part, "%s", what);
    }
    for (int k = 1; k < n; k++) {
        double d = sl[(size_t)k].s - sl[(size_t)k - 1].s;
        if (d <= 0)
            return fail_part(err, SF_EINVAL, sl[(size_t)k].part, "%s", "two slices at the same position");
        if (std::fabs(d - mean) > std::max(0.01, 0.01 * mean)) {
            char what[200];
            snprintf(what, sizeof what, "%.3g mm from the slice before it, %.3g mm on average: a slice is missing or the "
                     "parts are not one series (surfd does not resample uneven spacing)", d, mean);
            return fail_part(err, SF_EINVAL, sl[(size_t)k].part, "%s", what);
        }
    }
    out->g.nx = (int)a.cols, out->g.ny = (int)a.rows, out->g.nz = n;
    out->g.spacing[0] = a.spacing[1]; /* PixelSpacing is row spacing \ column spacing */
    out->g.spacing[1] = a.spacing[0];
    out->g.spacing[2] = mean;
    for (int i = 0; i < 3; i++) {
        out->g.origin[i] = sl[0].pos[i];
        out->axes[0][i] = r[i], out->axes[1][i] = c[i], out->axes[2][i] = nrm[i] / len;
    }
    out->g.type = ISO_I16;
    if (check_only)
        return 0;
    /* int16 when every rescaled value is a whole number within int16 (a CT in HU), float32 otherwise */
    bool whole = true;
    for (const slice &s : sl)
        whole = whole && s.slope == std::floor(s.slope) && s.intercept == std::floor(s.intercept);
    double lo = 0, hi = 0;
    for (const slice &s : sl)
        for (uint16_t raw : s.pixels) {
            double v = stored_value(s, raw) * s.slope + s.intercept;
            lo = std::min(lo, v), hi = std::max(hi, v);
        }
    whole = whole && lo >= -32768 && hi <= 32767;
    size_t plane = (size_t)a.rows * a.cols;
    out->g.type = whole ? ISO_I16 : ISO_F32;
    out->owned = malloc(plane * (size_t)n * (whole ? 2 : 4));
    if (!out->owned)
        return sf_fail(err, SF_ENOMEM, "", "out of memory for the series' samples");
    for (size_t k = 0; k < (size_t)n; k++)
        for (size_t i = 0; i < plane; i++) {
            double v = stored_value(sl[k], sl[k].pixels[i]) * sl[k].slope + sl[k].intercept;
            if (whole)
                ((int16_t *)out->owned)[k * plane + i] = (int16_t)v;
            else
                ((float *)out->owned)[k * plane + i] = (float)v;
        }
    out->g.samples = out->owned;
    return 0;
}
