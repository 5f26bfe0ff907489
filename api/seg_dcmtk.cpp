// seg_dcmtk.cpp - DICOM Segmentations out (seg.h) with DCMTK's dcmdata: the modules of PS3.3 A.51 -
// Patient, General Study (type 2 elements empty), General Series and Segmentation Series (SEG),
// Frame of Reference, General and Enhanced General Equipment, General Image, Image Pixel,
// Segmentation Image (BINARY), Multi-frame Functional Groups (Pixel Measures and Plane Orientation
// shared; Frame Content, Plane Position, Segment Identification and, with source images, Derivation
// Image per frame), Multi-frame Dimension (segment, then position), Common Instance Reference and
// SOP Common. Frames are packed bit after bit as they come (PS3.5 8.1.1), never held unpacked.
//
// Written with dcmdata rather than Debian's dcmseg (3.6.7): dcmseg keeps every frame's functional
// groups as objects of its own and copies each frame through them before it writes, and answers a
// broken rule with a bare condition; the subset written here is fixed, and dciodvfy checks it.
#include "seg.h"

#include <cmath>
#include <cstdint>
#include <cstring>
#include <new>
#include <string>
#include <vector>

#include "dcmtk_out.h"

static const char SEGMENTATION_SOP_CLASS[] = "1.2.840.10008.5.1.4.1.1.66.4";

struct seg_writer {
    const struct seg_grid *g;
    const struct seg_segment *s;
    int n;
    char study[100], frame[100];
    std::vector<std::pair<int, int>> frames; // (segment, slice) in the order added
    unsigned char *bits = nullptr;           // the frames, bit after bit
    size_t cap = 0;                          // bytes of bits
    uint64_t n_bits = 0;
};

extern "C" void seg_grid_free(struct seg_grid *g)
{
    free(g->pos);
    free(g->images);
    g->pos = NULL;
    g->images = NULL;
}

extern "C" void seg_cielab(const int rgb[3], unsigned lab[3])
{
    double lin[3];
    for (int k = 0; k < 3; k++) { /* sRGB's transfer function undone (IEC 61966-2-1) */
        double c = (rgb[k] < 0 ? 0 : rgb[k] > 255 ? 255 : rgb[k]) / 255.0;
        lin[k] = c <= 0.04045 ? c / 12.92 : pow((c + 0.055) / 1.055, 2.4);
    }
    /* to XYZ, relative to D65's white */
    double x = (0.4124564 * lin[0] + 0.3575761 * lin[1] + 0.1804375 * lin[2]) / 0.95047,
           y = 0.2126729 * lin[0] + 0.7151522 * lin[1] + 0.0721750 * lin[2],
           z = (0.0193339 * lin[0] + 0.1191920 * lin[1] + 0.9503041 * lin[2]) / 1.08883;
    auto f = [](double t) { return t > 216.0 / 24389 ? cbrt(t) : t * 24389 / 27 / 116 + 16.0 / 116; };
    double L = 116 * f(y) - 16, a = 500 * (f(x) - f(y)), b = 200 * (f(y) - f(z));
    double scaled[3] = {L / 100 * 65535, (a + 128) / 255 * 65535, (b + 128) / 255 * 65535};
    for (int k = 0; k < 3; k++)
        lab[k] = (unsigned)lround(scaled[k] < 0 ? 0 : scaled[k] > 65535 ? 65535 : scaled[k]);
}

extern "C" int seg_begin(const struct seg_grid *g, const struct seg_segment *s, int n, const char *study_uid,
                         const char *frame_uid, struct seg_writer **out, struct sf_err *err)
{
    *out = NULL;
    if (n < 1 || n > 65535)
        return sf_fail(err, SF_ELIMIT, "", "a Segmentation holds 1 to 65535 segments, not %d", n);
    double bits = (double)g->cols * g->rows * g->n_slices * n;
    if (g->cols < 1 || g->rows < 1 || g->n_slices < 1 || g->cols > 65535 || g->rows > 65535 || bits > (double)SEG_MAX_BITS)
        return sf_fail(err, SF_ELIMIT, "", "%d x %d x %d voxels x %d segments: a Segmentation here holds at most %llu "
                       "bits", g->cols, g->rows, g->n_slices, n, (unsigned long long)SEG_MAX_BITS);
    seg_writer *w = new (std::nothrow) seg_writer;
    if (!w)
        return sf_fail(err, SF_ENOMEM, "", "out of memory");
    w->g = g, w->s = s, w->n = n;
    dcm_uid(w->study, study_uid, SITE_STUDY_UID_ROOT);
    dcm_uid(w->frame, frame_uid, SITE_INSTANCE_UID_ROOT);
    *out = w;
    return 0;
}

extern "C" void seg_free(struct seg_writer *w)
{
    if (!w)
        return;
    free(w->bits);
    delete w;
}

extern "C" int seg_frame(struct seg_writer *w, int segment, int slice, const unsigned char *mask, struct sf_err *err)
{
    size_t px = (size_t)w->g->rows * (size_t)w->g->cols;
    if ((long)w->frames.size() >= SEG_MAX_FRAMES)
        return sf_fail(err, SF_ELIMIT, "", "over %ld frames: surfd reads no more from one Segmentation", SEG_MAX_FRAMES);
    size_t need = (size_t)((w->n_bits + px + 7) / 8);
    if (need > w->cap) {
        size_t cap = w->cap ? w->cap : 1 << 16;
        while (cap < need)
            cap *= 2;
        unsigned char *b = (unsigned char *)realloc(w->bits, cap);
        if (!b)
            return sf_fail(err, SF_ENOMEM, "", "out of memory for the Segmentation's frames");
        memset(b + w->cap, 0, cap - w->cap);
        w->bits = b, w->cap = cap;
    }
    try {
        w->frames.emplace_back(segment, slice);
    } catch (const std::bad_alloc &) {
        return sf_fail(err, SF_ENOMEM, "", "out of memory for the Segmentation's frames");
    }
    /* PS3.5 8.1.1: pixel k of the object is bit k % 8 of byte k / 8, frames one after another */
    for (size_t i = 0; i < px; i++)
        if (mask[i]) {
            uint64_t k = w->n_bits + i;
            w->bits[k >> 3] |= (unsigned char)(1u << (k & 7));
        }
    w->n_bits += px;
    return 0;
}

namespace {

std::string ds_values(const double *v, int n)
{
    std::string out;
    char b[32];
    for (int k = 0; k < n; k++) { /* DS holds 16 characters: 10 significant digits fit with sign and exponent */
        snprintf(b, sizeof b, "%s%.10g", k ? "\\" : "", fabs(v[k]) < 1e-12 ? 0.0 : v[k]);
        out += b;
    }
    return out;
}

bool code(DcmItem *it, const DcmTagKey &tag, const char *value, const char *scheme, const char *meaning)
{
    DcmItem *c = NULL;
    return it->findOrCreateSequenceItem(tag, c, -2).good() && c->putAndInsertString(DCM_CodeValue, value).good() &&
           c->putAndInsertString(DCM_CodingSchemeDesignator, scheme).good() &&
           c->putAndInsertString(DCM_CodeMeaning, meaning).good();
}

/* A sequence of tag, made empty and inserted into it (items are appended to it: findOrCreate's
 * walk to the end for each of 10^5 frames would be quadratic) */
DcmSequenceOfItems *sequence(DcmItem *it, const DcmTagKey &tag)
{
    DcmSequenceOfItems *sq = new DcmSequenceOfItems(tag);
    if (it->insert(sq, true).bad()) {
        delete sq;
        return NULL;
    }
    return sq;
}

DcmItem *append(DcmSequenceOfItems *sq)
{
    DcmItem *it = new DcmItem();
    if (sq->append(it).bad()) {
        delete it;
        return NULL;
    }
    return it;
}

/* SegmentLabel (LO, 64 characters, no backslash or control characters) of a model's name */
std::string label_of(const char *name)
{
    std::string out;
    for (const char *c = name && *name ? name : "model"; *c && out.size() < 64; c++)
        out += (unsigned char)*c < 0x20 || *c == '\\' ? ' ' : *c;
    return out;
}

bool header(DcmDataset *ds, const seg_writer *w, long n_frames)
{
    const struct seg_grid *g = w->g;
    char sop[100], series[100], date[16], tm[16];
    dcm_uid(sop, NULL, SITE_INSTANCE_UID_ROOT);
    dcm_uid(series, NULL, SITE_SERIES_UID_ROOT);
    dcm_now(date, tm);
    static const DcmTagKey EMPTY[] = {DCM_PatientName, DCM_PatientID, DCM_PatientBirthDate, DCM_PatientSex,
                                      DCM_StudyDate, DCM_StudyTime, DCM_ReferringPhysicianName, DCM_StudyID,
                                      DCM_AccessionNumber, DCM_PositionReferenceIndicator, DCM_ContentCreatorName};
    bool ok = ds->putAndInsertString(DCM_SpecificCharacterSet, "ISO_IR 192").good() &&
              ds->putAndInsertString(DCM_SOPClassUID, SEGMENTATION_SOP_CLASS).good() &&
              ds->putAndInsertString(DCM_SOPInstanceUID, sop).good() &&
              ds->putAndInsertString(DCM_InstanceCreationDate, date).good() &&
              ds->putAndInsertString(DCM_InstanceCreationTime, tm).good() &&
              ds->putAndInsertString(DCM_StudyInstanceUID, w->study).good() &&
              ds->putAndInsertString(DCM_SeriesInstanceUID, series).good() &&
              ds->putAndInsertString(DCM_Modality, "SEG").good() &&
              ds->putAndInsertString(DCM_SeriesNumber, "1").good() &&
              ds->putAndInsertString(DCM_InstanceNumber, "1").good() &&
              ds->putAndInsertString(DCM_FrameOfReferenceUID, w->frame).good() &&
              ds->putAndInsertString(DCM_Manufacturer, "surfd").good() &&
              ds->putAndInsertString(DCM_ManufacturerModelName, "surfd").good() &&
              ds->putAndInsertString(DCM_DeviceSerialNumber, "1").good() &&
              ds->putAndInsertString(DCM_SoftwareVersions, "surfd").good() &&
              ds->putAndInsertString(DCM_ImageType, "DERIVED\\PRIMARY").good() &&
              ds->putAndInsertString(DCM_ContentDate, date).good() && ds->putAndInsertString(DCM_ContentTime, tm).good() &&
              ds->putAndInsertString(DCM_ContentLabel, "SURFD").good() &&
              ds->putAndInsertString(DCM_ContentDescription, "surfd models voxelised").good() &&
              ds->putAndInsertUint16(DCM_SamplesPerPixel, 1).good() &&
              ds->putAndInsertString(DCM_PhotometricInterpretation, "MONOCHROME2").good() &&
              ds->putAndInsertUint16(DCM_Rows, (Uint16)g->rows).good() &&
              ds->putAndInsertUint16(DCM_Columns, (Uint16)g->cols).good() &&
              ds->putAndInsertUint16(DCM_BitsAllocated, 1).good() && ds->putAndInsertUint16(DCM_BitsStored, 1).good() &&
              ds->putAndInsertUint16(DCM_HighBit, 0).good() && ds->putAndInsertUint16(DCM_PixelRepresentation, 0).good() &&
              ds->putAndInsertString(DCM_LossyImageCompression, "00").good() &&
              ds->putAndInsertString(DCM_SegmentationType, "BINARY").good() &&
              ds->putAndInsertString(DCM_NumberOfFrames, std::to_string(n_frames).c_str()).good();
    for (size_t k = 0; ok && k < sizeof EMPTY / sizeof *EMPTY; k++)
        ok = ds->insertEmptyElement(EMPTY[k]).good();
    return ok;
}

bool segments(DcmDataset *ds, const seg_writer *w)
{
    DcmSequenceOfItems *sq = sequence(ds, DCM_SegmentSequence);
    bool ok = sq != NULL;
    for (int k = 0; ok && k < w->n; k++) {
        DcmItem *it = append(sq);
        unsigned lab[3];
        seg_cielab(w->s[k].color, lab);
        const Uint16 lab16[3] = {(Uint16)lab[0], (Uint16)lab[1], (Uint16)lab[2]};
        /* one generic code for every segment: what a model is made of is not known here (its
         * interpreted type, ORGAN or PTV, is the description) */
        ok = it && it->putAndInsertUint16(DCM_SegmentNumber, (Uint16)(k + 1)).good() &&
             it->putAndInsertString(DCM_SegmentLabel, label_of(w->s[k].label).c_str()).good() &&
             it->putAndInsertString(DCM_SegmentDescription, w->s[k].type && *w->s[k].type ? w->s[k].type : "ORGAN").good() &&
             it->putAndInsertString(DCM_SegmentAlgorithmType, "AUTOMATIC").good() &&
             it->putAndInsertString(DCM_SegmentAlgorithmName, "surfd").good() &&
             it->putAndInsertUint16Array(DCM_RecommendedDisplayCIELabValue, lab16, 3).good() &&
             code(it, DCM_SegmentedPropertyCategoryCodeSequence, "123037004", "SCT", "Anatomical Structure") &&
             code(it, DCM_SegmentedPropertyTypeCodeSequence, "85756007", "SCT", "Tissue");
    }
    return ok;
}

/* Multi-frame Dimension: frames indexed by segment, then by their position */
bool dimensions(DcmDataset *ds)
{
    char dim[100];
    dcm_uid(dim, NULL, SITE_INSTANCE_UID_ROOT);
    DcmItem *org = NULL;
    bool ok = ds->findOrCreateSequenceItem(DCM_DimensionOrganizationSequence, org, -2).good() &&
              org->putAndInsertString(DCM_DimensionOrganizationUID, dim).good() &&
              ds->putAndInsertString(DCM_DimensionOrganizationType, "3D").good();
    DcmSequenceOfItems *sq = ok ? sequence(ds, DCM_DimensionIndexSequence) : NULL;
    static const struct {
        DcmTagKey index, group;
        const char *label;
    } DIMS[] = {{DCM_ReferencedSegmentNumber, DCM_SegmentIdentificationSequence, "ReferencedSegmentNumber"},
                {DCM_ImagePositionPatient, DCM_PlanePositionSequence, "ImagePositionPatient"}};
    for (const auto &d : DIMS) {
        DcmItem *it = sq ? append(sq) : NULL;
        ok = ok && it && it->putAndInsertString(DCM_DimensionOrganizationUID, dim).good() &&
             it->putAndInsertTagKey(DCM_DimensionIndexPointer, d.index).good() &&
             it->putAndInsertTagKey(DCM_FunctionalGroupPointer, d.group).good() &&
             it->putAndInsertString(DCM_DimensionDescriptionLabel, d.label).good();
    }
    return ok;
}

bool functional_groups(DcmDataset *ds, const seg_writer *w)
{
    const struct seg_grid *g = w->g;
    DcmItem *shared = NULL, *pm = NULL, *po = NULL;
    bool ok = ds->findOrCreateSequenceItem(DCM_SharedFunctionalGroupsSequence, shared, -2).good() &&
              shared->findOrCreateSequenceItem(DCM_PixelMeasuresSequence, pm, -2).good() &&
              pm->putAndInsertString(DCM_PixelSpacing, ds_values(g->spacing, 2).c_str()).good() &&
              pm->putAndInsertString(DCM_SliceThickness, ds_values(&g->thickness, 1).c_str()).good() &&
              pm->putAndInsertString(DCM_SpacingBetweenSlices, ds_values(&g->thickness, 1).c_str()).good() &&
              shared->findOrCreateSequenceItem(DCM_PlaneOrientationSequence, po, -2).good() &&
              po->putAndInsertString(DCM_ImageOrientationPatient, ds_values(g->orient, 6).c_str()).good();
    DcmSequenceOfItems *sq = ok ? sequence(ds, DCM_PerFrameFunctionalGroupsSequence) : NULL;
    ok = ok && sq;
    for (size_t f = 0; ok && f < w->frames.size(); f++) {
        int segment = w->frames[f].first, slice = w->frames[f].second;
        DcmItem *it = append(sq), *fc = NULL, *pp = NULL, *si = NULL;
        const Uint32 index[2] = {(Uint32)segment, (Uint32)slice + 1};
        ok = it && it->findOrCreateSequenceItem(DCM_FrameContentSequence, fc, -2).good() &&
             fc->putAndInsertUint32Array(DCM_DimensionIndexValues, index, 2).good() &&
             it->findOrCreateSequenceItem(DCM_PlanePositionSequence, pp, -2).good() &&
             pp->putAndInsertString(DCM_ImagePositionPatient, ds_values(g->pos[slice], 3).c_str()).good() &&
             it->findOrCreateSequenceItem(DCM_SegmentIdentificationSequence, si, -2).good() &&
             si->putAndInsertUint16(DCM_ReferencedSegmentNumber, (Uint16)segment).good();
        if (ok && g->images) { /* the CT image this frame was drawn on */
            DcmItem *di = NULL, *src = NULL;
            ok = it->findOrCreateSequenceItem(DCM_DerivationImageSequence, di, -2).good() &&
                 code(di, DCM_DerivationCodeSequence, "113076", "DCM", "Segmentation") &&
                 di->findOrCreateSequenceItem(DCM_SourceImageSequence, src, -2).good() &&
                 src->putAndInsertString(DCM_ReferencedSOPClassUID, g->images[slice].sop_class).good() &&
                 src->putAndInsertString(DCM_ReferencedSOPInstanceUID, g->images[slice].sop_instance).good() &&
                 code(src, DCM_PurposeOfReferenceCodeSequence, "121322", "DCM",
                      "Source image for image processing operation");
        }
    }
    return ok;
}

/* Common Instance Reference: the series and the images the frames derive from */
bool references(DcmDataset *ds, const seg_writer *w)
{
    const struct seg_grid *g = w->g;
    if (!g->images)
        return true;
    std::vector<bool> used((size_t)g->n_slices);
    for (const auto &f : w->frames)
        used[(size_t)f.second] = true;
    DcmItem *series = NULL;
    bool ok = ds->findOrCreateSequenceItem(DCM_ReferencedSeriesSequence, series, -2).good() &&
              series->putAndInsertString(DCM_SeriesInstanceUID, g->series_uid).good();
    DcmSequenceOfItems *sq = ok ? sequence(series, DCM_ReferencedInstanceSequence) : NULL;
    ok = ok && sq;
    for (int k = 0; ok && k < g->n_slices; k++) {
        if (!used[(size_t)k])
            continue;
        DcmItem *it = append(sq);
        ok = it && it->putAndInsertString(DCM_ReferencedSOPClassUID, g->images[k].sop_class).good() &&
             it->putAndInsertString(DCM_ReferencedSOPInstanceUID, g->images[k].sop_instance).good();
    }
    return ok;
}

int end(seg_writer *w, unsigned char **out, size_t *out_len, struct sf_err *err)
{
    if (w->frames.empty())
        return sf_fail(err, SF_EINVAL, "", "no segment has a voxel on the grid: the models lie outside it, or are "
                       "thinner than its voxels");
    DcmFileFormat ff;
    DcmDataset *ds = ff.getDataset();
    bool ok = header(ds, w, (long)w->frames.size()) && segments(ds, w) && dimensions(ds) &&
              functional_groups(ds, w) && references(ds, w);
    /* OB of even length; the bits past the last frame are 0 (seg_frame zeroes what it grows) */
    size_t len = (size_t)((w->n_bits + 7) / 8), even = len + (len & 1);
    if (ok && even > 0xFFFFFFF0u)
        return sf_fail(err, SF_ELIMIT, "", "the frames are over 4 GiB, more than one DICOM element holds");
    Uint8 *px = NULL;
    if (ok) {
        DcmOtherByteOtherWord *pd = new DcmOtherByteOtherWord(DcmTag(DCM_PixelData, EVR_OB));
        ok = pd->createUint8Array((Uint32)even, px).good() && px;
        if (ok) {
            memcpy(px, w->bits, len);
            if (even > len)
                px[len] = 0;
            free(w->bits), w->bits = NULL; /* the element holds them now */
            ok = ds->insert(pd, true).good();
        } else {
            delete pd;
        }
    }
    if (!ok)
        return sf_fail(err, SF_ENOMEM, "", "out of memory writing the Segmentation");
    return dcm_write_object(ff, out, out_len, "the Segmentation", err);
}

} // namespace

extern "C" int seg_end(struct seg_writer *w, unsigned char **out, size_t *out_len, struct sf_err *err)
{
    *out = NULL;
    *out_len = 0;
    int rc;
    try { /* DCMTK's allocations throw: never past C */
        rc = end(w, out, out_len, err);
    } catch (const std::bad_alloc &) {
        rc = sf_fail(err, SF_ENOMEM, "", "out of memory writing the Segmentation");
    }
    seg_free(w);
    return rc;
}
