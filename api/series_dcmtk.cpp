// series_dcmtk.cpp - a DICOM CT/MR series to one sample grid (dicom_series.h), with DCMTK as the
// RT Structure Set reader uses it; one part that is a multi-frame image goes to frames_dcmtk.cpp.
// Uncompressed transfer syntaxes, and the compressed ones a PACS sends that Debian's DCMTK decodes:
// RLE (dcmdata), JPEG baseline, extended and lossless (dcmjpeg), JPEG-LS (dcmjpls); JPEG 2000, for
// which it has no codec, through OpenJPEG (j2k.h, dcmtk_image.h decode_j2k). A slice is decoded on the worker that reads the series
// (the check on the HTTP side reads its header alone), into Rows x Columns samples its header
// declared and the series' size was checked against; the slices are laid out by planes.h.
#include "dcmtk_image.h"
#include "dcmtk_in.h"
#include "dicom_instance.h"
#include "dicom_series.h"
#include "planes.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <new>
#include <vector>

namespace {

struct slice {
    int part;
    double pos[3], orient[6], spacing[2], slope = 1, intercept = 0;
    unsigned rows = 0, cols = 0, bits = 0, stored = 0;
    bool is_signed = false;
    std::vector<uint16_t> pixels; // 8-bit samples widened
};

int fail_part(struct sf_err *err, int code, int part, const char *fmt, const char *what)
{
    char where[48];
    planes_where(part, -1, where, sizeof where);
    return sf_fail(err, code, where, fmt, what);
}

/* The dataset of part k, read as dcmtk_in.h reads objects, into ff. */
int read_part(const struct part &p, int k, bool check_only, DcmFileFormat &ff, struct sf_err *err)
{
    char where[48];
    planes_where(k, -1, where, sizeof where);
    return dcm_read_object(p.data, p.len, where, check_only ? 4096 : DCM_MaxReadLength, ff, err);
}

int read_slice(DcmDataset *ds, int k, bool check_only, slice &sl, struct sf_err *err)
{
    char where[48];
    planes_where(k, -1, where, sizeof where);
    /* a multi-frame image is read alone (frames_dcmtk.cpp), its frames each decoded on their own:
     * DCMTK 3.6.7's decoders size their buffer as a frame times NumberOfFrames in 32 bits, which a
     * crafted header makes wrap (upstream 31ff413f9) */
    if (frames_multiframe(ds))
        return fail_part(err, SF_EINVAL, k, "%s", "a multi-frame image (Enhanced CT or MR, RT Dose, Segmentation) is "
                         "read alone: post it as the body, or as a series of one part");
    pixel_module h;
    int rc = read_pixel_module(ds, where, h, err); /* as a multi-frame image's is read */
    if (rc)
        return rc;
    if (h.bits != 8 && h.bits != 16)
        return fail_part(err, SF_EINVAL, k, "%s", "samples are one channel of 8 or 16 bits (a CT or MR image)");
    /* ImagePositionPatient: the slice's corner; ImageOrientationPatient: two direction cosines */
    if ((rc = check_range(err, where, "ImagePositionPatient (mm)", get_doubles(ds, DCM_ImagePositionPatient, sl.pos, 3),
                          sl.pos, 3, 0, RANGE_MAX_COORD, false)) ||
        (rc = check_range(err, where, "ImageOrientationPatient",
                          get_doubles(ds, DCM_ImageOrientationPatient, sl.orient, 6), sl.orient, 6, 0, 1 + ORIENT_EPS,
                          false)) ||
        (rc = check_range(err, where, "PixelSpacing (mm)", get_doubles(ds, DCM_PixelSpacing, sl.spacing, 2), sl.spacing,
                          2, RANGE_MIN_SPACING, RANGE_MAX_SPACING, false)))
        return rc;
    if (!(sl.spacing[0] > 0) || !(sl.spacing[1] > 0))
        return fail_part(err, SF_EINVAL, k, "%s", "PixelSpacing is not positive");
    if ((rc = check_range(err, where, "RescaleSlope", get_doubles(ds, DCM_RescaleSlope, &sl.slope, 1), &sl.slope, 1, 0,
                          SERIES_MAX_SLOPE, true)) ||
        (rc = check_range(err, where, "RescaleIntercept", get_doubles(ds, DCM_RescaleIntercept, &sl.intercept, 1),
                          &sl.intercept, 1, 0, SERIES_MAX_INTERCEPT, true)))
        return rc;
    if (sl.slope == 0)
        return fail_part(err, SF_EINVAL, k, "%s", "RescaleSlope is 0");
    sl.part = k, sl.rows = h.rows, sl.cols = h.cols, sl.bits = h.bits, sl.stored = h.stored;
    sl.is_signed = h.is_signed;
    if (check_only)
        return 0;
    if (h.encapsulated && (rc = decode_frame(ds, h.xfer, h.bits, &sl.stored, h.is_signed, where, err))) /* in place */
        return rc;
    size_t n = (size_t)h.rows * h.cols;
    if (h.bits == 16) {
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

/* The first slice's series, study and frame of reference UIDs into out (each "" unless a UID). */
void read_uids(DcmDataset *ds, struct series *out)
{
    const struct {
        DcmTagKey tag;
        char *to;
    } UIDS[] = {{DCM_SeriesInstanceUID, out->series_uid}, {DCM_StudyInstanceUID, out->study_uid},
                {DCM_FrameOfReferenceUID, out->frame_uid}};
    for (const auto &u : UIDS) {
        OFString v;
        if (ds->findAndGetOFString(u.tag, v).good() && dicom_uid_valid(v.c_str()))
            snprintf(u.to, 65, "%s", v.c_str());
    }
}

} // namespace

static int read_series(const struct part *parts, int n, bool check_only, size_t max_samples, int segment,
                       bool as_labels, struct series *out, struct sf_err *err);

extern "C" int series_read(const struct part *parts, int n, bool check_only, size_t max_samples, int segment,
                           bool as_labels, struct series *out, struct sf_err *err)
{
    memset(out, 0, sizeof *out);
    try { /* what C++ allocates here, DCMTK's buffers and the slices', may throw: never past C */
        return read_series(parts, n, check_only, max_samples, segment, as_labels, out, err);
    } catch (const std::bad_alloc &) {
        free(out->owned);
        free(out->segments);
        memset(out, 0, sizeof *out);
        return sf_fail(err, SF_ENOMEM, "/parts", "out of memory for the series");
    }
}

static int read_series(const struct part *parts, int n, bool check_only, size_t max_samples, int segment,
                       bool as_labels, struct series *out, struct sf_err *err)
{
    if (n < 1)
        return sf_fail(err, SF_EINVAL, "/parts", "a series is at least 2 slices (one DICOM image a part)");
    std::vector<slice> sl((size_t)n);
    for (int k = 0; k < n; k++) {
        DcmFileFormat ff;
        int rc = read_part(parts[k], k, check_only, ff, err);
        if (!rc && n == 1 && frames_multiframe(ff.getDataset()))
            return frames_read(ff.getDataset(), 0, check_only, max_samples, segment, as_labels, out, err);
        if (!rc && n == 1)
            rc = sf_fail(err, SF_EINVAL, "/parts", "one image of one frame: a series is at least 2 slices (one DICOM "
                         "image a part), or one multi-frame image (Enhanced CT or MR, RT Dose, Segmentation)");
        if (!rc)
            rc = read_slice(ff.getDataset(), k, check_only, sl[(size_t)k], err);
        if (!rc && k == 0)
            read_uids(ff.getDataset(), out);
        if (rc)
            return rc;
    }
    if (segment)
        return sf_fail(err, SF_EINVAL, "?segment", "segment chooses a segment of a DICOM Segmentation: this series is "
                       "not one");
    const slice &a = sl[0];
    if ((size_t)a.rows * a.cols * (size_t)n > max_samples)
        return sf_fail(err, SF_ELIMIT, "/parts", "the series has over %zu samples", max_samples);
    std::vector<struct plane> pl((size_t)n);
    for (int k = 0; k < n; k++) {
        const slice &s = sl[(size_t)k];
        if (s.bits != a.bits)
            return fail_part(err, SF_EINVAL, s.part, "%s", "a slice of another size than the first part's");
        struct plane &p = pl[(size_t)k];
        p.part = k, p.frame = -1, p.rows = s.rows, p.cols = s.cols, p.tag = k;
        memcpy(p.pos, s.pos, sizeof p.pos);
        memcpy(p.orient, s.orient, sizeof p.orient);
        memcpy(p.spacing, s.spacing, sizeof p.spacing);
    }
    struct planes_grid pg;
    int rc = planes_layout(pl.data(), n, false, max_samples, &pg, err);
    if (rc)
        return rc;
    out->g.nx = pg.nx, out->g.ny = pg.ny, out->g.nz = pg.nz;
    memcpy(out->g.spacing, pg.spacing, sizeof pg.spacing);
    memcpy(out->g.origin, pg.origin, sizeof pg.origin);
    memcpy(out->axes, pg.axes, sizeof pg.axes);
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
            double v = stored_value(s.bits, s.stored, s.is_signed, raw) * s.slope + s.intercept;
            lo = std::min(lo, v), hi = std::max(hi, v);
        }
    whole = whole && lo >= -32768 && hi <= 32767;
    size_t plane = (size_t)a.rows * a.cols;
    out->g.type = whole ? ISO_I16 : ISO_F32;
    out->owned = malloc(plane * (size_t)n * (whole ? 2 : 4));
    if (!out->owned)
        return sf_fail(err, SF_ENOMEM, "", "out of memory for the series' samples");
    for (size_t k = 0; k < (size_t)n; k++) {
        const slice &s = sl[(size_t)pl[k].tag]; /* the k-th along the normal */
        for (size_t i = 0; i < plane; i++) {
            double v = stored_value(s.bits, s.stored, s.is_signed, s.pixels[i]) * s.slope + s.intercept;
            if (whole)
                ((int16_t *)out->owned)[k * plane + i] = (int16_t)v;
            else
                ((float *)out->owned)[k * plane + i] = (float)v;
        }
    }
    out->g.samples = out->owned;
    return 0;
}
