// frames_dcmtk.cpp - one multi-frame DICOM image to one sample grid (dicom_series.h), with DCMTK as
// the series reader uses it: an image with the multi-frame functional groups (Enhanced CT and MR,
// PS3.3 C.7.6.16), an RT Dose (C.8.8.3) and a Segmentation (C.8.20). Each frame is a plane of
// planes.h (the series' rules); everything that sizes an allocation (NumberOfFrames x Rows x
// Columns, the pixel data's length or its fragments, the grid a sparse Segmentation spans) is
// checked before anything is decoded or allocated. Each frame is decoded on its own: compressed
// frames through a data set of that frame alone and the codecs a series' slices go through, so
// DCMTK 3.6.7 never sizes a buffer by NumberOfFrames (upstream 31ff413f9) and its decodeFrame, whose
// RLE path reads a fragment's header unchecked, is never called. Hand-written: DCMTK reads the
// elements but lays no frames out, and dcmseg/dcmrt are not in Debian's libdcmtk-dev headers alone.
#include "dcmtk_image.h"
#include "dicom_series.h"
#include "planes.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

namespace {

/* Frames an image may have: real RT Doses have some hundreds, Enhanced CTs some thousands, a
 * Segmentation a frame a segment a slice (100 segments of 500 slices: 50 000); each costs some
 * 150 bytes here before any pixel is read. */
#define FRAMES_MAX (1L << 18)
#define SEGMENTS_LISTED 16 /* segments a refusal names */

enum kind { FUNCTIONAL, DOSE, SEG };

struct frame {
    struct plane pl;
    double slope = 1, intercept = 0;
    unsigned segment = 0;
    unsigned long first = 0, n_frags = 0; /* its fragments (items of the pixel sequence), compressed */
};

struct image {
    DcmDataset *ds;
    int part;
    kind k;
    unsigned rows = 0, cols = 0, bits = 0, stored = 0;
    bool is_signed = false;
    long n_frames = 1;
    E_TransferSyntax xfer;
    bool encapsulated = false;
    bool fractional = false;
    unsigned max_fraction = 1;
    unsigned segment = 0; /* the segment read */
    std::vector<frame> f;
};

void where_frame(char *out, size_t cap, int part, long frame)
{
    if (frame < 0)
        snprintf(out, cap, "/parts/%d", part);
    else
        snprintf(out, cap, "/parts/%d/frames/%ld", part, frame);
}

int fail_at(struct sf_err *err, int code, int part, long frame, const char *what)
{
    char where[48];
    where_frame(where, sizeof where, part, frame);
    return sf_fail(err, code, where, "%s", what);
}

bool text_is(DcmItem *item, const DcmTagKey &tag, const char *value)
{
    OFString s;
    return item->findAndGetOFString(tag, s).good() && s == value;
}

/* The item of a functional group macro's sequence (PlanePositionSequence...) for a frame: in its own
 * item of the PerFrameFunctionalGroupsSequence, else in the SharedFunctionalGroupsSequence's item
 * (PS3.3 C.7.6.16.1.1: a macro is in one or the other), else NULL. */
DcmItem *group(DcmItem *per_frame, DcmItem *shared, const DcmTagKey &seq)
{
    DcmItem *it = nullptr;
    if (per_frame && per_frame->findAndGetSequenceItem(seq, it, 0).good() && it)
        return it;
    it = nullptr;
    if (shared && shared->findAndGetSequenceItem(seq, it, 0).good() && it)
        return it;
    return nullptr;
}

/* The image pixel module's elements (C.7.6.3), what the kind allows of them, and the caps on the
 * frames and their samples. */
int read_header(image &im, size_t max_samples, struct sf_err *err)
{
    DcmDataset *ds = im.ds;
    char what[240];
    Uint16 rows = 0, cols = 0, bits = 0, stored = 0, rep = 0, spp = 1;
    if (ds->findAndGetUint16(DCM_Rows, rows).bad() || ds->findAndGetUint16(DCM_Columns, cols).bad() || rows < 1 ||
        cols < 1)
        return fail_at(err, SF_EINVAL, im.part, -1, "a multi-frame image without Rows and Columns");
    ds->findAndGetUint16(DCM_BitsAllocated, bits);
    ds->findAndGetUint16(DCM_BitsStored, stored);
    ds->findAndGetUint16(DCM_PixelRepresentation, rep);
    ds->findAndGetUint16(DCM_SamplesPerPixel, spp);
    Sint32 frames = 1;
    if (ds->tagExists(DCM_NumberOfFrames) && ds->findAndGetSint32(DCM_NumberOfFrames, frames).bad())
        return fail_at(err, SF_EINVAL, im.part, -1, "NumberOfFrames is not a number");
    if (frames < 1 || frames > FRAMES_MAX) {
        snprintf(what, sizeof what, "NumberOfFrames is %ld: surfd reads 1 to %ld", (long)frames, FRAMES_MAX);
        return fail_at(err, frames < 1 ? SF_EINVAL : SF_ELIMIT, im.part, -1, what);
    }
    im.rows = rows, im.cols = cols, im.bits = bits, im.stored = stored && stored <= bits ? stored : bits;
    im.is_signed = rep == 1, im.n_frames = frames;
    if (spp != 1)
        return fail_at(err, SF_EINVAL, im.part, -1, "samples are one channel (SamplesPerPixel 1)");
    if (im.k == SEG) {
        OFString type;
        ds->findAndGetOFString(DCM_SegmentationType, type);
        im.fractional = type == "FRACTIONAL";
        if (type != "BINARY" && type != "FRACTIONAL") {
            snprintf(what, sizeof what, "SegmentationType \"%.16s\": surfd reads BINARY and FRACTIONAL segmentations "
                     "(PS3.3 C.8.20.2)", type.c_str());
            return fail_at(err, SF_EINVAL, im.part, -1, what);
        }
        if (bits != (im.fractional ? 8 : 1))
            return fail_at(err, SF_EINVAL, im.part, -1, im.fractional ? "a FRACTIONAL segmentation has BitsAllocated 8"
                                                                       : "a BINARY segmentation has BitsAllocated 1");
        im.is_signed = false;
        if (im.fractional) {
            Uint16 m = 0;
            if (ds->findAndGetUint16(DCM_MaximumFractionalValue, m).bad() || m < 1 || m > 255)
                return fail_at(err, SF_EINVAL, im.part, -1, "a FRACTIONAL segmentation's MaximumFractionalValue is 1 "
                               "to 255");
            im.max_fraction = m;
        }
    } else if (im.k == DOSE && bits != 16 && bits != 32) {
        return fail_at(err, SF_EINVAL, im.part, -1, "an RT Dose's samples are 16 or 32 bits (PS3.3 C.8.8.3.4.1)");
    } else if (im.k == FUNCTIONAL && bits != 8 && bits != 16) {
        return fail_at(err, SF_EINVAL, im.part, -1, "samples are one channel of 8 or 16 bits (a CT or MR image)");
    }
    /* the caps, in 64 bits, before anything is read */
    uint64_t plane = (uint64_t)rows * cols, total = plane * (uint64_t)frames;
    if (total > max_samples) {
        snprintf(what, sizeof what, "NumberOfFrames x Rows x Columns is %llu samples: over %zu",
                 (unsigned long long)total, max_samples);
        return fail_at(err, SF_ELIMIT, im.part, -1, what);
    }
    if (plane * (bits / 8) >= (1ull << 31))
        return fail_at(err, SF_ELIMIT, im.part, -1, "a frame of 2 GB or more (Rows x Columns x BitsAllocated)");
    im.xfer = ds->getOriginalXfer();
    DcmXfer x(im.xfer);
    im.encapsulated = x.isEncapsulated();
    if (im.encapsulated && !decodable(im.xfer)) {
        snprintf(what, sizeof what, "compressed pixel data (%s) is not read: send the image uncompressed, or as RLE, "
                 "JPEG (baseline, extended, lossless) or JPEG-LS", x.getXferName());
        return fail_at(err, SF_EINVAL, im.part, -1, what);
    }
    if (im.encapsulated && bits == 1)
        return fail_at(err, SF_EINVAL, im.part, -1, "a BINARY segmentation's pixel data is read uncompressed");
    if (im.encapsulated && total * (bits / 8) >= (1ull << 32))
        return fail_at(err, SF_ELIMIT, im.part, -1, "compressed frames of 4 GB or more in all");
    if (x.getByteOrder() == EBO_BigEndian && bits != 16)
        return fail_at(err, SF_EINVAL, im.part, -1, "Explicit VR Big Endian (retired) is read for 16-bit samples alone");
    return 0;
}

/* Geometry (C.7.6.2) and rescale of the frame items of a functional-groups image (C.7.6.16): each
 * frame's PlanePositionSequence, PlaneOrientationSequence, PixelMeasuresSequence and
 * PixelValueTransformationSequence, its own or the shared ones; a Segmentation's
 * SegmentIdentificationSequence (C.8.20.3). */
int read_functional(image &im, struct sf_err *err)
{
    DcmDataset *ds = im.ds;
    char what[200], where[48];
    DcmSequenceOfItems *pf = nullptr;
    if (ds->findAndGetSequence(DCM_PerFrameFunctionalGroupsSequence, pf).bad() || !pf ||
        pf->card() != (unsigned long)im.n_frames) {
        snprintf(what, sizeof what, "PerFrameFunctionalGroupsSequence has %lu items for NumberOfFrames %ld (PS3.3 "
                 "C.7.6.16: an item a frame)", pf ? pf->card() : 0ul, im.n_frames);
        return fail_at(err, SF_EINVAL, im.part, -1, what);
    }
    DcmItem *shared = nullptr;
    if (ds->findAndGetSequenceItem(DCM_SharedFunctionalGroupsSequence, shared, 0).bad())
        shared = nullptr;
    im.f.resize((size_t)im.n_frames);
    for (long i = 0; i < im.n_frames; i++) {
        frame &fr = im.f[(size_t)i];
        DcmItem *own = pf->getItem((unsigned long)i);
        where_frame(where, sizeof where, im.part, i);
        DcmItem *pp = group(own, shared, DCM_PlanePositionSequence), *po = group(own, shared, DCM_PlaneOrientationSequence),
                *pm = group(own, shared, DCM_PixelMeasuresSequence),
                *pv = group(own, shared, DCM_PixelValueTransformationSequence);
        int rc;
        if (!pp)
            return sf_fail(err, SF_EINVAL, where, "a frame without PlanePositionSequence (PS3.3 C.7.6.16.2.3): surfd "
                           "reads frames placed in patient coordinates");
        if ((rc = check_range(err, where, "PlanePositionSequence's ImagePositionPatient (mm)",
                              get_doubles(pp, DCM_ImagePositionPatient, fr.pl.pos, 3), fr.pl.pos, 3, 0, RANGE_MAX_COORD,
                              false)) ||
            (rc = check_range(err, where, "PlaneOrientationSequence's ImageOrientationPatient",
                              get_doubles(po, DCM_ImageOrientationPatient, fr.pl.orient, 6), fr.pl.orient, 6, 0,
                              1 + ORIENT_EPS, false)) ||
            (rc = check_range(err, where, "PixelMeasuresSequence's PixelSpacing (mm)",
                              get_doubles(pm, DCM_PixelSpacing, fr.pl.spacing, 2), fr.pl.spacing, 2, RANGE_MIN_SPACING,
                              RANGE_MAX_SPACING, false)))
            return rc;
        if (im.k != SEG &&
            ((rc = check_range(err, where, "RescaleSlope", get_doubles(pv, DCM_RescaleSlope, &fr.slope, 1), &fr.slope, 1,
                               0, SERIES_MAX_SLOPE, true)) ||
             (rc = check_range(err, where, "RescaleIntercept", get_doubles(pv, DCM_RescaleIntercept, &fr.intercept, 1),
                               &fr.intercept, 1, 0, SERIES_MAX_INTERCEPT, true))))
            return rc;
        if (fr.slope == 0)
            return sf_fail(err, SF_EINVAL, where, "RescaleSlope is 0");
        if (im.k == SEG) {
            DcmItem *si = group(own, shared, DCM_SegmentIdentificationSequence);
            Uint16 n = 0;
            if (!si || si->findAndGetUint16(DCM_ReferencedSegmentNumber, n).bad())
                return sf_fail(err, SF_EINVAL, where, "a frame without SegmentIdentificationSequence's "
                               "ReferencedSegmentNumber (PS3.3 C.8.20.3.1)");
            fr.segment = n;
        }
    }
    return 0;
}

/* An RT Dose's planes (C.8.8.3.2): ImagePositionPatient is the first frame's, and
 * GridFrameOffsetVector each frame's offset along the normal: relative to it when its first value
 * is 0, else absolute z (then the first value is ImagePositionPatient's z, the image axial);
 * DoseGridScaling makes the samples Gy (or DoseUnits' relative dose). */
int read_dose(image &im, struct sf_err *err)
{
    DcmDataset *ds = im.ds;
    char what[240], where[48];
    where_frame(where, sizeof where, im.part, -1);
    double pos[3], orient[6], spacing[2], scaling = 0;
    int rc;
    if ((rc = check_range(err, where, "ImagePositionPatient (mm)", get_doubles(ds, DCM_ImagePositionPatient, pos, 3),
                          pos, 3, 0, RANGE_MAX_COORD, false)) ||
        (rc = check_range(err, where, "ImageOrientationPatient", get_doubles(ds, DCM_ImageOrientationPatient, orient, 6),
                          orient, 6, 0, 1 + ORIENT_EPS, false)) ||
        (rc = check_range(err, where, "PixelSpacing (mm)", get_doubles(ds, DCM_PixelSpacing, spacing, 2), spacing, 2,
                          RANGE_MIN_SPACING, RANGE_MAX_SPACING, false)))
        return rc;
    /* DoseGridScaling is required with pixel data (Type 1C): without it the samples' unit, and so
     * what ?iso means, is unknown; refused rather than read as raw counts */
    int got = get_doubles(ds, DCM_DoseGridScaling, &scaling, 1);
    if (got == MISSING)
        return sf_fail(err, SF_EINVAL, where, "an RT Dose without DoseGridScaling (PS3.3 C.8.8.3: required with pixel "
                       "data): its samples' unit, and what iso means, is unknown");
    if ((rc = check_range(err, where, "DoseGridScaling", got, &scaling, 1, 0, SERIES_MAX_SLOPE, false)))
        return rc;
    if (!(scaling > 0))
        return sf_fail(err, SF_EINVAL, where, "DoseGridScaling is %g: a dose scales by a positive number", scaling);
    DcmElement *e = nullptr;
    unsigned long vm = ds->findAndGetElement(DCM_GridFrameOffsetVector, e).good() && e ? e->getVM() : 0;
    if (vm != (unsigned long)im.n_frames) {
        snprintf(what, sizeof what, "GridFrameOffsetVector has %lu values for NumberOfFrames %ld (PS3.3 C.8.8.3.2: a "
                 "value a frame)", vm, im.n_frames);
        return sf_fail(err, SF_EINVAL, where, "%s", what);
    }
    std::vector<double> off((size_t)im.n_frames);
    for (long i = 0; i < im.n_frames; i++) {
        Float64 v;
        if (ds->findAndGetFloat64(DCM_GridFrameOffsetVector, v, (unsigned long)i).bad() || !std::isfinite(v) ||
            std::fabs(v) > 2 * RANGE_MAX_COORD) {
            char fw[48];
            where_frame(fw, sizeof fw, im.part, i);
            return sf_fail(err, SF_EINVAL, fw, "GridFrameOffsetVector's value for this frame is not a number within "
                           "%g mm", 2 * RANGE_MAX_COORD);
        }
        off[(size_t)i] = v;
    }
    if (off[0] != 0) { /* absolute z: the standard allows it for axial doses alone */
        static const double AXIAL[6] = {1, 0, 0, 0, 1, 0};
        bool axial = true;
        for (int i = 0; i < 6; i++)
            axial = axial && std::fabs(orient[i] - AXIAL[i]) < 1e-4;
        if (!axial || std::fabs(off[0] - pos[2]) > std::max(1e-3, 1e-6 * std::fabs(pos[2]))) {
            snprintf(what, sizeof what, "GridFrameOffsetVector begins with %g: neither 0 (offsets from the first "
                     "frame) nor ImagePositionPatient's z, %g, of an axial dose (absolute z) (PS3.3 C.8.8.3.2)", off[0],
                     pos[2]);
            return sf_fail(err, SF_EINVAL, where, "%s", what);
        }
        for (double &v : off)
            v -= pos[2];
    }
    double r[3] = {orient[0], orient[1], orient[2]}, c[3] = {orient[3], orient[4], orient[5]};
    double nrm[3] = {r[1] * c[2] - r[2] * c[1], r[2] * c[0] - r[0] * c[2], r[0] * c[1] - r[1] * c[0]};
    double len = std::sqrt(nrm[0] * nrm[0] + nrm[1] * nrm[1] + nrm[2] * nrm[2]);
    if (!(len > 0.99 && len < 1.01))
        return sf_fail(err, SF_EINVAL, where, "ImageOrientationPatient is not two unit, perpendicular directions");
    im.f.resize((size_t)im.n_frames);
    for (long i = 0; i < im.n_frames; i++) {
        frame &fr = im.f[(size_t)i];
        for (int a = 0; a < 3; a++)
            fr.pl.pos[a] = pos[a] + off[(size_t)i] * nrm[a] / len;
        memcpy(fr.pl.orient, orient, sizeof orient);
        memcpy(fr.pl.spacing, spacing, sizeof spacing);
        fr.slope = scaling;
        if (!(std::fabs(fr.pl.pos[0]) <= RANGE_MAX_COORD && std::fabs(fr.pl.pos[1]) <= RANGE_MAX_COORD &&
              std::fabs(fr.pl.pos[2]) <= RANGE_MAX_COORD))
            return fail_at(err, SF_EINVAL, im.part, i, "GridFrameOffsetVector puts the frame past the range of "
                           "positions surfd reads");
    }
    return 0;
}

/* A label for a message: printable ASCII, at most 32 characters. */
std::string label_text(const OFString &s)
{
    std::string out;
    for (size_t i = 0; i < s.length() && out.size() < 32; i++)
        if (s[i] >= 0x20 && s[i] < 0x7f && s[i] != '"' && s[i] != '\\')
            out += s[i];
    while (!out.empty() && out.back() == ' ')
        out.pop_back();
    return out;
}

/* The segment a Segmentation is read for: ?segment (its SegmentNumber), or the only one; the
 * SegmentSequence's numbers (C.8.20.2) must be distinct, and every frame's one of them. */
int choose_segment(image &im, int segment, struct sf_err *err)
{
    char where[48];
    where_frame(where, sizeof where, im.part, -1);
    DcmSequenceOfItems *ss = nullptr;
    if (im.ds->findAndGetSequence(DCM_SegmentSequence, ss).bad() || !ss || ss->card() == 0)
        return sf_fail(err, SF_EINVAL, where, "a segmentation without SegmentSequence (PS3.3 C.8.20.2)");
    if (ss->card() > 65535)
        return sf_fail(err, SF_ELIMIT, where, "over 65535 segments");
    std::vector<std::pair<unsigned, std::string>> segs;
    for (unsigned long i = 0; i < ss->card(); i++) {
        DcmItem *it = ss->getItem(i);
        Uint16 n = 0;
        OFString label;
        if (!it || it->findAndGetUint16(DCM_SegmentNumber, n).bad() || n < 1)
            return sf_fail(err, SF_EINVAL, where, "SegmentSequence item %lu has no SegmentNumber (1 or more)", i);
        for (const auto &s : segs)
            if (s.first == n)
                return sf_fail(err, SF_EINVAL, where, "two segments numbered %u", (unsigned)n);
        it->findAndGetOFString(DCM_SegmentLabel, label);
        segs.emplace_back(n, label_text(label));
    }
    std::sort(segs.begin(), segs.end());
    std::string list;
    for (size_t i = 0; i < segs.size() && i < SEGMENTS_LISTED; i++)
        list += (i ? ", " : "") + std::to_string(segs[i].first) + (segs[i].second.empty() ? "" : " (" + segs[i].second + ")");
    if (segs.size() > SEGMENTS_LISTED)
        list += ", ...";
    if (segment == 0 && segs.size() > 1)
        return sf_fail(err, SF_EINVAL, "?segment", "the segmentation holds %zu segments: %s; choose one with "
                       "?segment=N", segs.size(), list.c_str());
    unsigned want = segment ? (unsigned)segment : segs[0].first;
    bool listed = false;
    for (const auto &s : segs)
        listed = listed || s.first == want;
    if (!listed)
        return sf_fail(err, SF_EINVAL, "?segment", "the segmentation has no segment %u: its segments are %s", want,
                       list.c_str());
    im.segment = want;
    size_t used = 0;
    for (size_t i = 0; i < im.f.size(); i++) {
        bool known = false;
        for (const auto &s : segs)
            known = known || s.first == im.f[i].segment;
        if (!known) {
            char what[160];
            snprintf(what, sizeof what, "the frame's ReferencedSegmentNumber %u is none of SegmentSequence's "
                     "segments (%s)", im.f[i].segment, list.c_str());
            return fail_at(err, SF_EINVAL, im.part, (long)i, what);
        }
        used += im.f[i].segment == want;
    }
    if (!used)
        return sf_fail(err, SF_EINVAL, segment ? "?segment" : where,
                       "segment %u has no frames: it is empty", want);
    return 0;
}

/* The pixel data as its header says: uncompressed, long enough for every frame (the first frame it
 * cuts short named); compressed, each frame's fragments found (one a frame; else by the Basic
 * Offset Table, else, JPEG's, by their start-of-image markers). */
int check_pixels(image &im, DcmPixelSequence **seq_out, struct sf_err *err)
{
    char what[200];
    DcmElement *pe = nullptr;
    if (im.ds->findAndGetElement(DCM_PixelData, pe).bad() || !pe)
        return fail_at(err, SF_EINVAL, im.part, -1, "an image without pixel data");
    uint64_t plane = (uint64_t)im.rows * im.cols;
    if (!im.encapsulated) {
        uint64_t len = pe->getLength(), bits_per_frame = plane * im.bits;
        if ((uint64_t)len * 8 < bits_per_frame * (uint64_t)im.n_frames) {
            snprintf(what, sizeof what, "the pixel data (%llu bytes) ends before this frame: NumberOfFrames (%ld) "
                     "frames of Rows x Columns x BitsAllocated make %llu", (unsigned long long)len, im.n_frames,
                     (unsigned long long)((bits_per_frame * (uint64_t)im.n_frames + 7) / 8));
            return fail_at(err, SF_EINVAL, im.part, (long)(len * 8 / bits_per_frame), what);
        }
        return 0;
    }
    DcmPixelSequence *seq = nullptr;
    if (OFstatic_cast(DcmPixelData *, pe)->getEncapsulatedRepresentation(im.xfer, nullptr, seq).bad() || !seq ||
        seq->card() < 2)
        return fail_at(err, SF_EINVAL, im.part, -1, "compressed pixel data without fragments");
    unsigned long n_frag = seq->card() - 1, frames = (unsigned long)im.n_frames;
    std::vector<unsigned long> start; /* each frame's first item */
    if (n_frag == frames) {
        for (unsigned long i = 0; i < frames; i++)
            start.push_back(i + 1);
    } else if (im.xfer == EXS_RLELossless) {
        snprintf(what, sizeof what, "RLE holds one fragment a frame (PS3.5 A.4.2): %lu fragments for %lu frames",
                 n_frag, frames);
        return fail_at(err, SF_EINVAL, im.part, -1, what);
    } else {
        DcmPixelItem *bot = nullptr;
        Uint8 *b = nullptr;
        seq->getItem(bot, 0);
        Uint32 blen = bot ? bot->getLength() : 0;
        if (blen == 4 * frames && bot->getUint8Array(b).good() && b) { /* the Basic Offset Table (PS3.5 A.4) */
            uint64_t at = 0;
            unsigned long item = 1;
            for (unsigned long i = 0; i < frames; i++) {
                uint64_t o = (uint64_t)b[4 * i] | (uint64_t)b[4 * i + 1] << 8 | (uint64_t)b[4 * i + 2] << 16 |
                             (uint64_t)b[4 * i + 3] << 24;
                while (item <= n_frag && at < o) {
                    DcmPixelItem *it = nullptr;
                    seq->getItem(it, item);
                    at += 8 + (it ? it->getLength() : 0);
                    item++;
                }
                if (at != o || item > n_frag || (i > 0 && item <= start.back()))
                    return fail_at(err, SF_EINVAL, im.part, (long)i, "the Basic Offset Table puts this frame where no "
                                   "fragment begins");
                start.push_back(item);
            }
        } else if (blen == 0) { /* JPEG's frames begin with a start-of-image marker */
            for (unsigned long j = 1; j <= n_frag; j++) {
                DcmPixelItem *it = nullptr;
                Uint8 *d = nullptr;
                if (seq->getItem(it, j).good() && it && it->getLength() >= 2 && it->getUint8Array(d).good() && d &&
                    d[0] == 0xff && d[1] == 0xd8)
                    start.push_back(j);
            }
            if (start.size() != frames || start[0] != 1) {
                snprintf(what, sizeof what, "%lu fragments begin %zu JPEG images for %lu frames, and no offset table "
                         "says which are whose", n_frag, start.size(), frames);
                return fail_at(err, SF_EINVAL, im.part, -1, what);
            }
        } else {
            snprintf(what, sizeof what, "the Basic Offset Table has %lu bytes for %lu frames (4 a frame)",
                     (unsigned long)blen, frames);
            return fail_at(err, SF_EINVAL, im.part, -1, what);
        }
    }
    for (unsigned long i = 0; i < frames; i++) {
        im.f[i].first = start[i];
        im.f[i].n_frags = (i + 1 < frames ? start[i + 1] : n_frag + 1) - start[i];
    }
    *seq_out = seq;
    return 0;
}

/* The raw samples (stored bits, unsigned) of frame i into out, and the frame's BitsStored (a
 * decoder's narrower precision) into *stored. */
int frame_samples(image &im, DcmPixelSequence *seq, long i, std::vector<uint32_t> &out, unsigned *stored,
                  struct sf_err *err)
{
    char where[48];
    where_frame(where, sizeof where, im.part, i);
    size_t n = (size_t)im.rows * im.cols;
    out.resize(n);
    *stored = im.stored;
    const Uint8 *b = nullptr;
    uint64_t first = 0; /* the frame's first sample in b */
    DcmDataset one;
    if (!im.encapsulated) {
        DcmElement *pe = nullptr;
        Uint8 *p = nullptr;
        if (im.ds->findAndGetElement(DCM_PixelData, pe).bad() || !pe || pe->getUint8Array(p).bad() || !p)
            return sf_fail(err, SF_EINVAL, where, "the pixel data cannot be read");
        b = p;
        first = (uint64_t)n * (uint64_t)i;
    } else { /* a data set of this frame alone, decoded as a series' slice is */
        const frame &fr = im.f[(size_t)i];
        OFString photometric = "MONOCHROME2";
        im.ds->findAndGetOFString(DCM_PhotometricInterpretation, photometric);
        DcmPixelSequence *ps = new DcmPixelSequence(DCM_PixelSequenceTag);
        ps->insert(new DcmPixelItem(DCM_PixelItemTag)); /* an empty offset table */
        for (unsigned long j = fr.first; j < fr.first + fr.n_frags; j++) {
            DcmPixelItem *src = nullptr;
            Uint8 *d = nullptr;
            if (seq->getItem(src, j).bad() || !src || (src->getLength() && (src->getUint8Array(d).bad() || !d))) {
                delete ps;
                return sf_fail(err, SF_EINVAL, where, "a fragment of the frame cannot be read");
            }
            DcmPixelItem *it = new DcmPixelItem(DCM_PixelItemTag);
            if (src->getLength())
                it->putUint8Array(d, src->getLength());
            ps->insert(it);
        }
        DcmPixelData *px = new DcmPixelData(DCM_PixelData);
        px->putOriginalRepresentation(im.xfer, nullptr, ps); /* px owns ps */
        if (one.insert(px).bad()) {
            delete px;
            return sf_fail(err, SF_ENOMEM, where, "out of memory for the frame");
        }
        one.putAndInsertUint16(DCM_Rows, (Uint16)im.rows);
        one.putAndInsertUint16(DCM_Columns, (Uint16)im.cols);
        one.putAndInsertUint16(DCM_BitsAllocated, (Uint16)im.bits);
        one.putAndInsertUint16(DCM_BitsStored, (Uint16)im.stored);
        one.putAndInsertUint16(DCM_HighBit, (Uint16)(im.stored - 1));
        one.putAndInsertUint16(DCM_PixelRepresentation, im.is_signed ? 1 : 0);
        one.putAndInsertUint16(DCM_SamplesPerPixel, 1);
        one.putAndInsertOFStringArray(DCM_PhotometricInterpretation, photometric);
        int rc = decode_frame(&one, im.bits, stored, where, err);
        if (rc)
            return rc;
        DcmElement *pe = nullptr;
        Uint8 *p = nullptr;
        if (one.findAndGetElement(DCM_PixelData, pe).bad() || !pe || pe->getUint8Array(p).bad() || !p ||
            pe->getLength() < n * (im.bits / 8))
            return sf_fail(err, SF_EINVAL, where, "the frame decodes to fewer samples than Rows x Columns");
        b = p;
    }
    for (size_t j = 0; j < n; j++) {
        uint64_t k = first + j;
        switch (im.bits) {
        case 1: out[j] = (b[k >> 3] >> (k & 7)) & 1u; break;
        case 8: out[j] = b[k]; break;
        case 16: out[j] = (uint32_t)b[2 * k] | (uint32_t)b[2 * k + 1] << 8; break;
        default:
            out[j] = (uint32_t)b[4 * k] | (uint32_t)b[4 * k + 1] << 8 | (uint32_t)b[4 * k + 2] << 16 |
                     (uint32_t)b[4 * k + 3] << 24;
        }
    }
    return 0;
}

/* Each frame of the segment read (every frame, but a Segmentation's) decoded into its slice of
 * grid (im's planes laid out as pl). *whole: every value so far a whole number within int16. */
int fill_grid(image &im, DcmPixelSequence *seq, const std::vector<struct plane> &pl, void *grid, bool *whole,
              struct sf_err *err)
{
    size_t plane = (size_t)im.rows * im.cols;
    bool binary = im.k == SEG && !im.fractional;
    int rc, k = im.part;
    std::vector<uint32_t> raw;
    for (const struct plane &p : pl) {
        const frame &fr = im.f[(size_t)p.tag];
        if (im.k == SEG && fr.segment != im.segment)
            continue;
        unsigned stored;
        if ((rc = frame_samples(im, seq, p.tag, raw, &stored, err)))
            return rc;
        size_t base = (size_t)p.z * plane;
        if (binary) {
            for (size_t j = 0; j < plane; j++)
                ((uint8_t *)grid)[base + j] = (uint8_t)raw[j];
            continue;
        }
        float *dst = (float *)grid + base;
        if (im.k == SEG) {
            for (size_t j = 0; j < plane; j++) {
                if (raw[j] > im.max_fraction) {
                    char what[120];
                    snprintf(what, sizeof what, "a sample of %u, over MaximumFractionalValue %u", raw[j],
                             im.max_fraction);
                    return fail_at(err, SF_EINVAL, k, p.tag, what);
                }
                dst[j] = (float)((double)raw[j] / im.max_fraction);
            }
            continue;
        }
        *whole = *whole && fr.slope == std::floor(fr.slope) && fr.intercept == std::floor(fr.intercept);
        for (size_t j = 0; j < plane; j++) {
            double v = stored_value(im.bits, stored, im.is_signed, raw[j]) * fr.slope + fr.intercept;
            *whole = *whole && v >= -32768 && v <= 32767;
            dst[j] = (float)v;
        }
    }
    return 0;
}

kind kind_of(DcmDataset *ds)
{
    if (text_is(ds, DCM_SOPClassUID, UID_RTDoseStorage) || text_is(ds, DCM_Modality, "RTDOSE"))
        return DOSE;
    if (text_is(ds, DCM_SOPClassUID, UID_SegmentationStorage) || text_is(ds, DCM_Modality, "SEG"))
        return SEG;
    return FUNCTIONAL;
}

} // namespace

bool frames_multiframe(DcmDataset *ds)
{
    Sint32 frames = 1;
    if (ds->tagExists(DCM_NumberOfFrames) && (ds->findAndGetSint32(DCM_NumberOfFrames, frames).bad() || frames != 1))
        return true;
    return kind_of(ds) != FUNCTIONAL || ds->tagExists(DCM_PerFrameFunctionalGroupsSequence);
}

int frames_read(DcmDataset *ds, int k, bool check_only, size_t max_samples, int segment, struct series *out,
                struct sf_err *err)
{
    image im;
    im.ds = ds, im.part = k, im.k = kind_of(ds);
    int rc;
    if (im.k == FUNCTIONAL && !ds->tagExists(DCM_PerFrameFunctionalGroupsSequence))
        return fail_at(err, SF_EINVAL, k, -1, "a multi-frame image without per-frame positions: surfd reads Enhanced "
                       "CT and MR images (functional groups, PS3.3 C.7.6.16), RT Doses (C.8.8.3) and Segmentations "
                       "(C.8.20)");
    if ((rc = read_header(im, max_samples, err)))
        return rc;
    if ((rc = im.k == DOSE ? read_dose(im, err) : read_functional(im, err)))
        return rc;
    if (im.k == SEG && (rc = choose_segment(im, segment, err)))
        return rc;
    if (im.k != SEG && segment)
        return sf_fail(err, SF_EINVAL, "?segment", "segment chooses a segment of a DICOM Segmentation: this image is "
                       "not one");
    DcmPixelSequence *seq = nullptr;
    if ((rc = check_pixels(im, &seq, err)))
        return rc;
    /* the planes: a Segmentation's every frame, whichever segment, makes its grid */
    std::vector<struct plane> pl(im.f.size());
    for (size_t i = 0; i < im.f.size(); i++) {
        pl[i] = im.f[i].pl;
        pl[i].part = k, pl[i].frame = (int)i, pl[i].rows = im.rows, pl[i].cols = im.cols, pl[i].tag = (int)i;
    }
    struct planes_grid pg;
    if ((rc = planes_layout(pl.data(), (int)pl.size(), im.k == SEG, max_samples, &pg, err)))
        return rc;
    size_t plane = (size_t)im.rows * im.cols, count = plane * (size_t)pg.nz;
    if (im.k == SEG) { /* one frame of the segment a slice */
        std::vector<long> at((size_t)pg.nz, -1);
        for (const struct plane &p : pl) {
            if (im.f[(size_t)p.tag].segment != im.segment)
                continue;
            if (at[(size_t)p.z] >= 0) {
                char what[120];
                snprintf(what, sizeof what, "two frames of segment %u at one position (the other: frame %ld)",
                         im.segment, at[(size_t)p.z]);
                return fail_at(err, SF_EINVAL, k, p.tag, what);
            }
            at[(size_t)p.z] = p.tag;
        }
    }
    out->g.nx = pg.nx, out->g.ny = pg.ny, out->g.nz = pg.nz;
    memcpy(out->g.spacing, pg.spacing, sizeof pg.spacing);
    memcpy(out->g.origin, pg.origin, sizeof pg.origin);
    memcpy(out->axes, pg.axes, sizeof pg.axes);
    bool binary = im.k == SEG && !im.fractional;
    out->g.type = binary ? ISO_U8 : ISO_F32;
    out->typed = im.k == SEG;
    if (check_only)
        return 0;
    /* the grid: float32 (shrunk to int16 below when every value is a whole number within it), a
     * binary segmentation's uint8; a Segmentation's slices without a frame of its segment are 0 */
    out->owned = calloc(count ? count : 1, binary ? 1 : sizeof(float));
    if (!out->owned)
        return sf_fail(err, SF_ENOMEM, "", "out of memory for the image's samples");
    out->g.samples = out->owned;
    bool whole = im.k != SEG;
    if ((rc = fill_grid(im, seq, pl, out->owned, &whole, err))) {
        free(out->owned);
        out->owned = NULL, out->g.samples = NULL;
        return rc;
    }
    if (whole) { /* int16, as a series' whole values are: in place, each sample written after its float is read */
        unsigned char *b = (unsigned char *)out->owned;
        for (size_t j = 0; j < count; j++) {
            float v;
            memcpy(&v, b + 4 * j, 4);
            int16_t s = (int16_t)v;
            memcpy(b + 2 * j, &s, 2);
        }
        void *less = realloc(out->owned, count ? 2 * count : 1);
        if (less)
            out->owned = less;
        out->g.samples = out->owned;
        out->g.type = ISO_I16;
    }
    return 0;
}
