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
#include <array>
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
/* Fragments one compressed frame may span (PS3.5 A.4: its stream in one or more items). Writers
 * put a frame in one, or cut it at a size (dcmtk's +fs 1: 1 KB), so a frame of B bytes of samples
 * takes B / 1024 + 1 for any stream no longer than them; this allows twice that and 16 more. Past
 * it, the fragments are refused: each is a walk of DCMTK's list in its decoders (getItem), so a
 * frame trailed by 100 000 empty fragments took 27 s. Empty ones count as any other: the standard
 * sets fragments no least length, and counted, they are bounded with the rest. */
unsigned long frags_max(unsigned rows, unsigned cols, unsigned bits)
{
    return 16 + (unsigned long)((uint64_t)rows * cols * (bits / 8) / 512);
}

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
    unsigned segment = 0; /* the segment read (as_labels: 0 for every segment) */
    bool as_labels = false; /* a Segmentation read as a label map of SegmentNumbers */
    std::vector<std::pair<unsigned, std::string>> labels; /* as_labels: the segments read, number and label */
    std::vector<frame> f;
    std::vector<DcmPixelItem *> frags; /* compressed: the pixel sequence's items, the offset table first */
};

int fail_at(struct sf_err *err, int code, int part, long frame, const char *what)
{
    char where[48];
    planes_where(part, frame, where, sizeof where);
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

/* The image pixel module (C.7.6.3) as a series' slice's is read (dcmtk_image.h), what the kind
 * allows of it, and the caps on the frames and their samples. */
int read_header(image &im, size_t max_samples, struct sf_err *err)
{
    DcmDataset *ds = im.ds;
    char what[240], where[48];
    planes_where(im.part, -1, where, sizeof where);
    pixel_module h;
    int rc = read_pixel_module(ds, where, h, err);
    if (rc)
        return rc;
    Sint32 frames = 1;
    if (ds->tagExists(DCM_NumberOfFrames) && ds->findAndGetSint32(DCM_NumberOfFrames, frames).bad())
        return fail_at(err, SF_EINVAL, im.part, -1, "NumberOfFrames is not a number");
    if (frames < 1 || frames > FRAMES_MAX) {
        snprintf(what, sizeof what, "NumberOfFrames is %ld: surfd reads 1 to %ld", (long)frames, FRAMES_MAX);
        return fail_at(err, frames < 1 ? SF_EINVAL : SF_ELIMIT, im.part, -1, what);
    }
    unsigned bits = h.bits;
    im.rows = h.rows, im.cols = h.cols, im.bits = bits, im.stored = h.stored, im.is_signed = h.is_signed;
    im.n_frames = frames, im.xfer = h.xfer, im.encapsulated = h.encapsulated;
    if (im.k == SEG) {
        OFString type;
        ds->findAndGetOFString(DCM_SegmentationType, type);
        im.fractional = type == "FRACTIONAL";
        if (type != "BINARY" && type != "FRACTIONAL") {
            snprintf(what, sizeof what, "SegmentationType \"%.16s\": surfd reads BINARY and FRACTIONAL segmentations "
                     "(PS3.3 C.8.20.2)", type.c_str());
            return fail_at(err, SF_EINVAL, im.part, -1, what);
        }
        if (bits != (im.fractional ? 8u : 1u))
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
    uint64_t total = (uint64_t)im.rows * im.cols * (uint64_t)frames;
    if (total > max_samples) {
        snprintf(what, sizeof what, "NumberOfFrames x Rows x Columns is %llu samples: over %zu",
                 (unsigned long long)total, max_samples);
        return fail_at(err, SF_ELIMIT, im.part, -1, what);
    }
    if (im.encapsulated && bits == 1)
        return fail_at(err, SF_EINVAL, im.part, -1, "a BINARY segmentation's pixel data is read uncompressed");
    if (im.encapsulated && total * (bits / 8) >= (1ull << 32))
        return fail_at(err, SF_ELIMIT, im.part, -1, "compressed frames of 4 GB or more in all");
    if (DcmXfer(im.xfer).getByteOrder() == EBO_BigEndian && bits != 16)
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
    std::vector<DcmItem *> per = items_of<DcmItem>(pf);
    if (per.size() != (size_t)im.n_frames)
        return fail_at(err, SF_EINVAL, im.part, -1, "PerFrameFunctionalGroupsSequence's items cannot be read");
    im.f.resize((size_t)im.n_frames);
    for (long i = 0; i < im.n_frames; i++) {
        frame &fr = im.f[(size_t)i];
        DcmItem *own = per[(size_t)i];
        planes_where(im.part, i, where, sizeof where);
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

/* GridFrameOffsetVector's n values (e: its element, of n values) into off, each read once: -1, or
 * the first frame whose value is not a finite number within twice the range of positions. The
 * element's text is split here: DCMTK's findAndGetFloat64(tag, v, i) finds value i by reading the
 * text from its start, n^2 / 2 steps for n frames. Another VR (FD in explicit VR) is read by
 * index, as before: direct for a binary one, refused at once for other text. */
long grid_offsets(DcmElement *e, size_t n, std::vector<double> &off)
{
    off.assign(n, 0);
    OFString text;
    /* the text as it is: normalised, DCMTK would read it value by value, each found from the start */
    bool is_text = e->ident() == EVR_DS && e->getOFStringArray(text, OFFalse).good();
    size_t at = 0;
    for (size_t i = 0; i < n; i++) {
        double v = NAN;
        if (is_text) {
            size_t end = text.find('\\', at);
            if (end == OFString_npos)
                end = text.length();
            size_t a = at, b = end;
            while (a < b && text[a] == ' ')
                a++;
            while (b > a && text[b - 1] == ' ')
                b--;
            OFBool ok = OFFalse;
            OFString one = text.substr(a, b - a);
            if (!one.empty()) {
                v = OFStandard::atof(one.c_str(), &ok);
                if (!ok)
                    v = NAN;
            }
            at = end + 1;
        } else {
            Float64 f;
            if (e->getFloat64(f, (unsigned long)i).good())
                v = f;
        }
        if (!std::isfinite(v) || std::fabs(v) > 2 * RANGE_MAX_COORD)
            return (long)i;
        off[i] = v;
    }
    return -1;
}

/* An RT Dose's planes (C.8.8.3.2): ImagePositionPatient is the first frame's, and
 * GridFrameOffsetVector each frame's offset along the normal: relative to it when its first value
 * is 0, else absolute z (then the first value is ImagePositionPatient's z, the image axial);
 * DoseGridScaling makes the samples Gy (or DoseUnits' relative dose). */
int read_dose(image &im, struct sf_err *err)
{
    DcmDataset *ds = im.ds;
    char what[240], where[48];
    planes_where(im.part, -1, where, sizeof where);
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
    std::vector<double> off;
    long bad = grid_offsets(e, (size_t)im.n_frames, off);
    if (bad >= 0) {
        char fw[48];
        planes_where(im.part, bad, fw, sizeof fw);
        return sf_fail(err, SF_EINVAL, fw, "GridFrameOffsetVector's value for this frame is not a number within "
                       "%g mm", 2 * RANGE_MAX_COORD);
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

/* A label for a message (or, of up to 63 characters, a model's name): printable ASCII. */
std::string label_text(const OFString &s, size_t most = 32)
{
    std::string out;
    for (size_t i = 0; i < s.length() && out.size() < most; i++)
        if (s[i] >= 0x20 && s[i] < 0x7f && s[i] != '"' && s[i] != '\\')
            out += s[i];
    while (!out.empty() && out.back() == ' ')
        out.pop_back();
    return out;
}

/* The segment a Segmentation is read for: ?segment (its SegmentNumber), or the only one, or every
 * one (as a label map, without ?segment: im.segment 0, and im.labels those with frames); the
 * SegmentSequence's numbers (C.8.20.2) must be distinct, and every frame's one of them. The
 * numbers are sorted once and looked up by halving (65 535 segments checked pair by pair, each
 * frame against each, took 13.6 s). */
int choose_segment(image &im, int segment, struct sf_err *err)
{
    char where[48];
    planes_where(im.part, -1, where, sizeof where);
    DcmSequenceOfItems *ss = nullptr;
    if (im.ds->findAndGetSequence(DCM_SegmentSequence, ss).bad() || !ss || ss->card() == 0)
        return sf_fail(err, SF_EINVAL, where, "a segmentation without SegmentSequence (PS3.3 C.8.20.2)");
    if (ss->card() > 65535)
        return sf_fail(err, SF_ELIMIT, where, "over 65535 segments");
    std::vector<DcmItem *> items = items_of<DcmItem>(ss);
    std::vector<std::pair<unsigned, DcmItem *>> segs; /* number, item: sorted by number */
    segs.reserve(items.size());
    for (size_t i = 0; i < items.size(); i++) {
        Uint16 n = 0;
        if (!items[i] || items[i]->findAndGetUint16(DCM_SegmentNumber, n).bad() || n < 1)
            return sf_fail(err, SF_EINVAL, where, "SegmentSequence item %zu has no SegmentNumber (1 or more)", i);
        segs.emplace_back(n, items[i]);
    }
    std::sort(segs.begin(), segs.end(), [](const auto &a, const auto &b) { return a.first < b.first; });
    for (size_t i = 1; i < segs.size(); i++)
        if (segs[i].first == segs[i - 1].first)
            return sf_fail(err, SF_EINVAL, where, "two segments numbered %u", segs[i].first);
    auto index = [&segs](unsigned n) { /* n's place in segs, or segs.size() */
        auto at = std::lower_bound(segs.begin(), segs.end(), n, [](const auto &s, unsigned v) { return s.first < v; });
        return at != segs.end() && at->first == n ? (size_t)(at - segs.begin()) : segs.size();
    };
    auto has = [&](unsigned n) { return index(n) < segs.size(); };
    std::string list;
    for (size_t i = 0; i < segs.size() && i < SEGMENTS_LISTED; i++) {
        OFString label;
        segs[i].second->findAndGetOFString(DCM_SegmentLabel, label);
        std::string l = label_text(label);
        list += (i ? ", " : "") + std::to_string(segs[i].first) + (l.empty() ? "" : " (" + l + ")");
    }
    if (segs.size() > SEGMENTS_LISTED)
        list += ", ...";
    bool every = im.as_labels && segment == 0;
    if (segment == 0 && segs.size() > 1 && !every)
        return sf_fail(err, SF_EINVAL, "?segment", "the segmentation holds %zu segments: %s; choose one with "
                       "?segment=N", segs.size(), list.c_str());
    unsigned want = segment ? (unsigned)segment : every ? 0 : segs[0].first;
    if (want && !has(want))
        return sf_fail(err, SF_EINVAL, "?segment", "the segmentation has no segment %u: its segments are %s", want,
                       list.c_str());
    im.segment = want;
    size_t used = 0;
    std::vector<bool> framed(segs.size()); /* the segments with a frame: a label map's labels (the rest are empty) */
    for (size_t i = 0; i < im.f.size(); i++) {
        if (im.f[i].segment != want && !has(im.f[i].segment)) {
            char what[160];
            snprintf(what, sizeof what, "the frame's ReferencedSegmentNumber %u is none of SegmentSequence's "
                     "segments (%s)", im.f[i].segment, list.c_str());
            return fail_at(err, SF_EINVAL, im.part, (long)i, what);
        }
        used += every || im.f[i].segment == want;
        if (im.as_labels)
            framed[index(im.f[i].segment)] = true;
    }
    if (!used)
        return sf_fail(err, SF_EINVAL, segment ? "?segment" : where,
                       "segment %u has no frames: it is empty", want);
    for (size_t i = 0; im.as_labels && i < segs.size(); i++)
        if (framed[i] && (every || segs[i].first == want)) {
            OFString label;
            segs[i].second->findAndGetOFString(DCM_SegmentLabel, label);
            im.labels.emplace_back(segs[i].first, label_text(label, 63));
        }
    return 0;
}

/* The pixel data as its header says: uncompressed, long enough for every frame (the first frame it
 * cuts short named); compressed, each frame's fragments found (one a frame; else by the Basic
 * Offset Table, else, JPEG's, by their start-of-image markers), at most frags_max a frame (the
 * fragments walked once, into im.frags). */
int check_pixels(image &im, struct sf_err *err)
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
    unsigned long cap = frags_max(im.rows, im.cols, im.bits);
    if (n_frag > frames * cap) { /* before they are walked */
        snprintf(what, sizeof what, "%lu fragments for %lu frames: surfd reads at most %lu a frame of %ux%u samples "
                 "(PS3.5 A.4)", n_frag, frames, cap, im.rows, im.cols);
        return fail_at(err, SF_ELIMIT, im.part, -1, what);
    }
    im.frags = items_of<DcmPixelItem>(seq);
    const std::vector<DcmPixelItem *> &fr = im.frags;
    if (fr.size() != n_frag + 1)
        return fail_at(err, SF_EINVAL, im.part, -1, "the compressed pixel data's fragments cannot be read");
    std::vector<unsigned long> start; /* each frame's first item */
    if (n_frag == frames) {
        for (unsigned long i = 0; i < frames; i++)
            start.push_back(i + 1);
    } else if (im.xfer == EXS_RLELossless) {
        snprintf(what, sizeof what, "RLE holds one fragment a frame (PS3.5 A.4.2): %lu fragments for %lu frames",
                 n_frag, frames);
        return fail_at(err, SF_EINVAL, im.part, -1, what);
    } else {
        DcmPixelItem *bot = fr[0];
        Uint8 *b = nullptr;
        Uint32 blen = bot ? bot->getLength() : 0;
        if (blen == 4 * frames && bot->getUint8Array(b).good() && b) { /* the Basic Offset Table (PS3.5 A.4) */
            uint64_t at = 0;
            unsigned long item = 1;
            for (unsigned long i = 0; i < frames; i++) {
                uint64_t o = (uint64_t)b[4 * i] | (uint64_t)b[4 * i + 1] << 8 | (uint64_t)b[4 * i + 2] << 16 |
                             (uint64_t)b[4 * i + 3] << 24;
                for (; item <= n_frag && at < o; item++)
                    at += 8 + (fr[item] ? fr[item]->getLength() : 0);
                if (at != o || item > n_frag || (i > 0 && item <= start.back()))
                    return fail_at(err, SF_EINVAL, im.part, (long)i, "the Basic Offset Table puts this frame where no "
                                   "fragment begins");
                start.push_back(item);
            }
        } else if (blen == 0) { /* JPEG's frames begin with a start-of-image marker */
            for (unsigned long j = 1; j <= n_frag; j++) {
                Uint8 *d = nullptr;
                if (fr[j] && fr[j]->getLength() >= 2 && fr[j]->getUint8Array(d).good() && d && d[0] == 0xff &&
                    d[1] == 0xd8)
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
        if (im.f[i].n_frags > cap) {
            snprintf(what, sizeof what, "the frame spans %lu fragments: surfd reads at most %lu a frame of %ux%u "
                     "samples (PS3.5 A.4)", im.f[i].n_frags, cap, im.rows, im.cols);
            return fail_at(err, SF_ELIMIT, im.part, (long)i, what);
        }
    }
    return 0;
}

/* The raw samples (stored bits, unsigned) of frame i into out, and the frame's BitsStored (a
 * decoder's narrower precision) into *stored. */
int frame_samples(image &im, long i, std::vector<uint32_t> &out, unsigned *stored, struct sf_err *err)
{
    char where[48];
    planes_where(im.part, i, where, sizeof where);
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
            DcmPixelItem *src = im.frags[j];
            Uint8 *d = nullptr;
            if (!src || (src->getLength() && (src->getUint8Array(d).bad() || !d))) {
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
        int rc = decode_frame(&one, im.xfer, im.bits, stored, im.is_signed, where, err);
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

/* Whether a Segmentation's frame is one of the segments read. */
bool segment_read(const image &im, const frame &fr)
{
    return im.k != SEG || fr.segment == im.segment || (im.as_labels && im.segment == 0);
}

/* The label of segment n read as a label map, for a message: " (LABEL)" or "". */
std::string label_of(const image &im, unsigned n)
{
    auto at = std::lower_bound(im.labels.begin(), im.labels.end(), n, [](const auto &l, unsigned v) { return l.first < v; });
    return at != im.labels.end() && at->first == n && !at->second.empty() ? " (" + label_text(at->second.c_str()) + ")"
                                                                          : "";
}

/* A Segmentation's frame into a uint16 label map's slice: its SegmentNumber where it holds the
 * segment (binary 1, fractional over half its maximum); a sample another segment holds already is
 * refused, naming both (a label map holds one label a sample). */
int fill_labels(const image &im, const struct plane &p, const std::vector<uint32_t> &raw, uint16_t *dst,
                struct sf_err *err)
{
    unsigned n = im.f[(size_t)p.tag].segment;
    for (size_t j = 0; j < raw.size(); j++) {
        if (raw[j] > im.max_fraction)
            break; /* (fill_grid's message) */
        if (im.fractional ? 2 * raw[j] <= im.max_fraction : !raw[j])
            continue;
        if (dst[j] && dst[j] != n) {
            char what[200];
            snprintf(what, sizeof what, "segments %u%s and %u%s overlap in this frame: a label map holds one segment a "
                     "sample (read each with ?segment=N)", (unsigned)dst[j], label_of(im, dst[j]).c_str(), n,
                     label_of(im, n).c_str());
            return fail_at(err, SF_EINVAL, im.part, p.tag, what);
        }
        dst[j] = (uint16_t)n;
    }
    return 0;
}

/* Each frame of the segments read (every frame, but a Segmentation's) decoded into its slice of
 * grid (im's planes laid out as pl). *whole: every value so far a whole number within int16. */
int fill_grid(image &im, const std::vector<struct plane> &pl, void *grid, bool *whole, struct sf_err *err)
{
    size_t plane = (size_t)im.rows * im.cols;
    bool binary = im.k == SEG && !im.fractional && !im.as_labels;
    int rc, k = im.part;
    std::vector<uint32_t> raw;
    for (const struct plane &p : pl) {
        const frame &fr = im.f[(size_t)p.tag];
        if (!segment_read(im, fr))
            continue;
        unsigned stored;
        if ((rc = frame_samples(im, p.tag, raw, &stored, err)))
            return rc;
        size_t base = (size_t)p.z * plane;
        if (im.as_labels && (rc = fill_labels(im, p, raw, (uint16_t *)grid + base, err)))
            return rc;
        if (binary) {
            for (size_t j = 0; j < plane; j++)
                ((uint8_t *)grid)[base + j] = (uint8_t)raw[j];
            continue;
        }
        if (im.k == SEG) {
            float *dst = (float *)grid + base;
            for (size_t j = 0; j < plane; j++) {
                if (raw[j] > im.max_fraction) {
                    char what[120];
                    snprintf(what, sizeof what, "a sample of %u, over MaximumFractionalValue %u", raw[j],
                             im.max_fraction);
                    return fail_at(err, SF_EINVAL, k, p.tag, what);
                }
                if (!im.as_labels)
                    dst[j] = (float)((double)raw[j] / im.max_fraction);
            }
            continue;
        }
        float *dst = (float *)grid + base;
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

int frames_read(DcmDataset *ds, int k, bool check_only, size_t max_samples, int segment, bool as_labels,
                struct series *out, struct sf_err *err)
{
    image im;
    im.ds = ds, im.part = k, im.k = kind_of(ds);
    im.as_labels = as_labels && im.k == SEG;
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
    if ((rc = check_pixels(im, err)))
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
    if (im.k == SEG) { /* one frame of a segment a slice: (segment, slice, frame) sorted, neighbours compared */
        std::vector<std::array<long, 3>> at;
        for (const struct plane &p : pl)
            if (segment_read(im, im.f[(size_t)p.tag]))
                at.push_back({(long)im.f[(size_t)p.tag].segment, p.z, p.tag});
        std::sort(at.begin(), at.end());
        for (size_t i = 1; i < at.size(); i++)
            if (at[i][0] == at[i - 1][0] && at[i][1] == at[i - 1][1]) {
                char what[120];
                snprintf(what, sizeof what, "two frames of segment %ld at one position (the other: frame %ld)",
                         at[i][0], at[i - 1][2]);
                return fail_at(err, SF_EINVAL, k, at[i][2], what);
            }
    }
    out->g.nx = pg.nx, out->g.ny = pg.ny, out->g.nz = pg.nz;
    memcpy(out->g.spacing, pg.spacing, sizeof pg.spacing);
    memcpy(out->g.origin, pg.origin, sizeof pg.origin);
    memcpy(out->axes, pg.axes, sizeof pg.axes);
    bool binary = im.k == SEG && !im.fractional && !im.as_labels;
    out->g.type = binary ? ISO_U8 : im.as_labels ? ISO_U16 : ISO_F32;
    out->typed = im.k == SEG;
    if (im.as_labels) {
        out->label_map = true;
        out->segments = (struct series_segment *)calloc(im.labels.size(), sizeof *out->segments);
        if (!out->segments)
            return sf_fail(err, SF_ENOMEM, "", "out of memory for the segments");
        out->n_segments = (int)im.labels.size();
        for (size_t i = 0; i < im.labels.size(); i++) {
            out->segments[i].number = im.labels[i].first;
            snprintf(out->segments[i].label, sizeof out->segments[i].label, "%s", im.labels[i].second.c_str());
        }
    }
    if (check_only)
        return 0;
    /* the grid: float32 (shrunk to int16 below when every value is a whole number within it), a
     * binary segmentation's uint8; a Segmentation's slices without a frame of its segment are 0 */
    out->owned = calloc(count ? count : 1, binary ? 1 : im.as_labels ? 2 : sizeof(float));
    if (!out->owned) {
        free(out->segments);
        out->segments = NULL, out->n_segments = 0;
        return sf_fail(err, SF_ENOMEM, "", "out of memory for the image's samples");
    }
    out->g.samples = out->owned;
    bool whole = im.k != SEG;
    if ((rc = fill_grid(im, pl, out->owned, &whole, err))) {
        free(out->owned);
        free(out->segments);
        out->owned = NULL, out->g.samples = NULL, out->segments = NULL, out->n_segments = 0;
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
