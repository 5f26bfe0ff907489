// rtstruct_dcmtk.cpp - DCMTK for RT Structure Sets (series_dcmtk.cpp reads image series): an RT
// Structure Set in memory to contour sets, and models' sections back to one (rtstruct_write).
// ROI names come from StructureSetROISequence, contours from ROIContourSequence (CLOSED_PLANAR
// only; POINT and OPEN_* contours are skipped, as they bound nothing), colours from there too,
// interpreted types from RTROIObservationsSequence, the series' images from
// ReferencedFrameOfReferenceSequence. Slice z is the contour's own z (ContourData is x, y, z
// triples in patient coordinates); a contour whose z varies is not planar and is refused. No other
// element of the object is read (KEPT below lists them all).
#include "dcmtk_out.h"
#include "dcmtk_in.h"
#include "rtstruct.h"

#include <dcmtk/config/osconfig.h>
#include <dcmtk/dcmdata/dctk.h>
#include <dcmtk/dcmdata/dcistrmb.h>
#include <dcmtk/dcmdata/dcostrmb.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <map>
#include <string>
#include <vector>

static const char RT_STRUCT_SOP_CLASS[] = "1.2.840.10008.5.1.4.1.1.481.3";
#define PLANAR_EPS 1e-3 /* mm: z spread allowed within one CLOSED_PLANAR contour */
/* mm from the origin: patient coordinates are within a metre or two of it; 1 km keeps any real
 * contour and every product the modelling makes of them (areas, volumes) finite */
#define RTSTRUCT_MAX_COORD 1e6

extern "C" void rtstruct_free(struct rt_roi *rois, int n_rois)
{
    for (int k = 0; k < n_rois && rois; k++)
        contour_set_free(&rois[k].cs);
    if (rois && n_rois > 0) /* one array, shared by every ROI */
        free((void *)rois[0].images);
    free(rois);
}

/* Parses buf into ff: SF_EFORMAT (in err) when it is not DICOM, SF_EINVAL when not an RT Structure Set. */
static int read_object(const void *buf, size_t len, DcmFileFormat &ff, struct sf_err *err)
{
    int rc = dcm_read_object(buf, len, "", DCM_MaxReadLength, ff, err);
    if (rc)
        return rc;
    OFString sop;
    if (ff.getDataset()->findAndGetOFString(DCM_SOPClassUID, sop).bad() || sop != RT_STRUCT_SOP_CLASS)
        return sf_fail(err, SF_EINVAL, "/SOPClassUID", "the DICOM object is not an RT Structure Set");
    return 0;
}

/* What of a structure set is kept (rtstruct_strip) and read: elements, and sequences with what
 * their items keep (a list ends at an entry of no tag). */
struct kept {
    DcmTagKey tag;
    const struct kept *items; /* NULL: an element */
};
static const DcmTagKey END = DCM_UndefinedTagKey;
static const struct kept IMAGE_REF[] = {{DCM_ReferencedSOPClassUID, NULL}, {DCM_ReferencedSOPInstanceUID, NULL}, {END, NULL}};
static const struct kept CONTOUR[] = {{DCM_ContourGeometricType, NULL}, {DCM_NumberOfContourPoints, NULL},
                                      {DCM_ContourData, NULL}, {DCM_ContourImageSequence, IMAGE_REF}, {END, NULL}};
static const struct kept ROI_CONTOUR[] = {{DCM_ReferencedROINumber, NULL}, {DCM_ROIDisplayColor, NULL},
                                          {DCM_ContourSequence, CONTOUR}, {END, NULL}};
static const struct kept ROI[] = {{DCM_ROINumber, NULL}, {DCM_ROIName, NULL}, {DCM_ReferencedFrameOfReferenceUID, NULL},
                                  {END, NULL}};
static const struct kept OBSERVATION[] = {{DCM_ObservationNumber, NULL}, {DCM_ReferencedROINumber, NULL},
                                          {DCM_RTROIInterpretedType, NULL}, {END, NULL}};
static const struct kept SERIES[] = {{DCM_SeriesInstanceUID, NULL}, {DCM_ContourImageSequence, IMAGE_REF}, {END, NULL}};
static const struct kept STUDY[] = {{DCM_ReferencedSOPClassUID, NULL}, {DCM_ReferencedSOPInstanceUID, NULL},
                                    {DCM_RTReferencedSeriesSequence, SERIES}, {END, NULL}};
static const struct kept FRAME[] = {{DCM_FrameOfReferenceUID, NULL}, {DCM_RTReferencedStudySequence, STUDY}, {END, NULL}};
static const struct kept KEPT[] = {{DCM_StudyInstanceUID, NULL},
                                   {DCM_ReferencedFrameOfReferenceSequence, FRAME},
                                   {DCM_StructureSetROISequence, ROI},
                                   {DCM_ROIContourSequence, ROI_CONTOUR},
                                   {DCM_RTROIObservationsSequence, OBSERVATION},
                                   {END, NULL}};

/* A sequence's items in order, walked once: DCMTK's getItem(i) walks its list from the start each
 * time, so indexed loops were quadratic in what a file declares (a structure set of 100 000 empty
 * StructureSetROISequence items, 2 MB, took 17.8 s). */
static std::vector<DcmItem *> items_of(DcmSequenceOfItems *seq)
{
    std::vector<DcmItem *> v;
    if (seq) {
        v.reserve(seq->card());
        for (DcmObject *o = seq->nextInContainer(NULL); o; o = seq->nextInContainer(o))
            v.push_back(static_cast<DcmItem *>(o));
    }
    return v;
}

/* Copies what spec keeps from one item to another (a sequence kept even when empty: its ROIs read
 * as skipped, as they were); false when out of memory. */
static bool copy_kept(DcmItem *from, DcmItem *to, const struct kept *spec)
{
    for (const struct kept *k = spec; k->tag != END; k++) {
        if (!k->items) {
            DcmElement *el = NULL;
            if (from->findAndGetElement(k->tag, el).good() && el && to->insert(static_cast<DcmElement *>(el->clone())).bad())
                return false;
            continue;
        }
        DcmSequenceOfItems *seq = NULL;
        if (from->findAndGetSequence(k->tag, seq).bad() || !seq)
            continue;
        if (seq->card() == 0 && to->insert(new DcmSequenceOfItems(k->tag)).bad())
            return false;
        for (DcmItem *src : items_of(seq)) {
            DcmItem *item = NULL;
            if (to->findOrCreateSequenceItem(k->tag, item, -2).bad() || !copy_kept(src, item, k->items))
                return false;
        }
    }
    return true;
}

extern "C" int rtstruct_strip(const void *buf, size_t len, unsigned char **out, size_t *out_len, struct sf_err *err)
{
    *out = NULL;
    *out_len = 0;
    DcmFileFormat ff;
    int rc = read_object(buf, len, ff, err);
    if (rc)
        return rc;
    DcmDataset *ds = ff.getDataset();
    DcmFileFormat kept;
    DcmDataset *kd = kept.getDataset();
    char uid[100];
    bool ok = kd->putAndInsertString(DCM_SOPClassUID, RT_STRUCT_SOP_CLASS).good() &&
              kd->putAndInsertString(DCM_SOPInstanceUID, dcmGenerateUniqueIdentifier(uid, SITE_INSTANCE_UID_ROOT)).good() &&
              kd->putAndInsertString(DCM_Modality, "RTSTRUCT").good() && copy_kept(ds, kd, KEPT);
    if (!ok)
        return sf_fail(err, SF_ENOMEM, "", "out of memory copying the structure set");
    return dcm_write_object(kept, out, out_len, "the stripped object", err);
}

extern "C" int rtstruct_read(const void *buf, size_t len, struct rt_roi **out, int *n_out, struct sf_err *err)
{
    *out = NULL;
    *n_out = 0;
    DcmFileFormat ff;
    int rc0 = read_object(buf, len, ff, err);
    if (rc0)
        return rc0;
    DcmDataset *ds = ff.getDataset();

    std::map<long, std::string> names, frames; // ROI Number -> ROI Name, its frame of reference
    OFString study;
    ds->findAndGetOFString(DCM_StudyInstanceUID, study);
    DcmSequenceOfItems *seq = NULL;
    if (ds->findAndGetSequence(DCM_StructureSetROISequence, seq).good() && seq)
        for (DcmItem *it : items_of(seq)) {
            Sint32 num = 0;
            OFString name, frame;
            if (it->findAndGetSint32(DCM_ROINumber, num).good()) {
                it->findAndGetOFString(DCM_ROIName, name);
                it->findAndGetOFString(DCM_ReferencedFrameOfReferenceUID, frame);
                names[num] = name.c_str();
                frames[num] = frame.c_str();
            }
        }
    std::map<long, std::string> types; // ROI Number -> its RTROIInterpretedType
    seq = NULL;
    if (ds->findAndGetSequence(DCM_RTROIObservationsSequence, seq).good() && seq)
        for (DcmItem *it : items_of(seq)) {
            Sint32 num = 0;
            OFString type;
            if (it->findAndGetSint32(DCM_ReferencedROINumber, num).good() &&
                it->findAndGetOFString(DCM_RTROIInterpretedType, type).good())
                types[num] = type.c_str();
        }
    /* the first referenced series with images: the one the contours were drawn on */
    OFString series;
    std::vector<DcmItem *> image_items;
    seq = NULL;
    if (ds->findAndGetSequence(DCM_ReferencedFrameOfReferenceSequence, seq).good() && seq)
        for (DcmItem *fr : items_of(seq)) {
            DcmSequenceOfItems *st = NULL;
            if (image_items.empty() && fr->findAndGetSequence(DCM_RTReferencedStudySequence, st).good() && st)
                for (DcmItem *sti : items_of(st)) {
                    DcmSequenceOfItems *se = NULL;
                    if (image_items.empty() && sti->findAndGetSequence(DCM_RTReferencedSeriesSequence, se).good() && se)
                        for (DcmItem *sei : items_of(se)) {
                            DcmSequenceOfItems *im = NULL;
                            if (image_items.empty() && sei->findAndGetSequence(DCM_ContourImageSequence, im).good() && im &&
                                im->card() <= RTSTRUCT_MAX_IMAGES && sei->findAndGetOFString(DCM_SeriesInstanceUID, series).good())
                                image_items = items_of(im);
                        }
                }
        }
    std::map<std::string, double> image_z; // SOP Instance UID -> the plane of a contour that references it
    DcmSequenceOfItems *rcs = NULL;
    if (ds->findAndGetSequence(DCM_ROIContourSequence, rcs).bad() || !rcs)
        return sf_fail(err, SF_EINVAL, "/ROIContourSequence", "the structure set has no ROIContourSequence");
    if (rcs->card() > RTSTRUCT_MAX_ROIS)
        return sf_fail(err, SF_ELIMIT, "/ROIContourSequence", "more than %d ROIs", RTSTRUCT_MAX_ROIS);

    /* room for every ROI Contour item and every named ROI without one (listed as skipped) */
    struct rt_roi *rois = (struct rt_roi *)calloc(rcs->card() + names.size() + 1, sizeof *rois);
    if (!rois)
        return sf_fail(err, SF_ENOMEM, "", "out of memory");
    int n = 0, rc = 0;
    std::vector<DcmItem *> rois_in = items_of(rcs);
    for (unsigned long r = 0; r < rois_in.size() && !rc; r++) {
        DcmItem *roi = rois_in[r];
        Sint32 num = 0;
        roi->findAndGetSint32(DCM_ReferencedROINumber, num);
        DcmSequenceOfItems *cseq = NULL;
        struct rt_roi *out_roi = &rois[n];
        out_roi->number = num;
        snprintf(out_roi->name, sizeof out_roi->name, "%s", names.count(num) ? names[num].c_str() : "");
        snprintf(out_roi->frame_uid, sizeof out_roi->frame_uid, "%s", frames.count(num) ? frames[num].c_str() : "");
        snprintf(out_roi->study_uid, sizeof out_roi->study_uid, "%s", study.c_str());
        snprintf(out_roi->type, sizeof out_roi->type, "%s", types.count(num) ? types[num].c_str() : "");
        out_roi->color[0] = out_roi->color[1] = out_roi->color[2] = -1;
        Sint32 rgb[3]; /* IS: three integers, each 0..255 */
        if (roi->findAndGetSint32(DCM_ROIDisplayColor, rgb[0], 0).good() && roi->findAndGetSint32(DCM_ROIDisplayColor, rgb[1], 1).good() &&
            roi->findAndGetSint32(DCM_ROIDisplayColor, rgb[2], 2).good() && rgb[0] >= 0 && rgb[0] < 256 && rgb[1] >= 0 &&
            rgb[1] < 256 && rgb[2] >= 0 && rgb[2] < 256)
            for (int c = 0; c < 3; c++)
                out_roi->color[c] = (int)rgb[c];
        names.erase(num); // what stays in names has no ROI Contour item
        if (roi->findAndGetSequence(DCM_ContourSequence, cseq).bad() || !cseq || cseq->card() == 0) {
            out_roi->skipped = "no contours"; // nothing to model, listed
            n++;
            continue;
        }
        if (cseq->card() > CONTOUR_MAX_SLICES) {
            rc = sf_fail(err, SF_ELIMIT, "/ROIContourSequence", "ROI %d has more than %d contours", (int)num,
                         CONTOUR_MAX_SLICES);
            break;
        }
        out_roi->cs.s = (struct contour_slice *)calloc(cseq->card(), sizeof *out_roi->cs.s);
        if (!out_roi->cs.s) {
            rc = sf_fail(err, SF_ENOMEM, "", "out of memory");
            break;
        }
        n++;
        std::vector<DcmItem *> contours_in = items_of(cseq);
        for (unsigned long k = 0; k < contours_in.size() && !rc; k++) {
            DcmItem *ci = contours_in[k];
            char ptr[128];
            snprintf(ptr, sizeof ptr, "/ROIContourSequence/%lu/ContourSequence/%lu/ContourData", r, k);
            OFString type;
            ci->findAndGetOFString(DCM_ContourGeometricType, type);
            if (type != "CLOSED_PLANAR")
                continue;
            DcmElement *el = NULL;
            if (ci->findAndGetElement(DCM_ContourData, el).bad() || !el || el->getVM() < 9 || el->getVM() % 3) {
                rc = sf_fail(err, SF_EINVAL, ptr, "ContourData must hold at least 3 (x, y, z) points");
                break;
            }
            unsigned long np = el->getVM() / 3;
            if (np > CONTOUR_MAX_POINTS) {
                rc = sf_fail(err, SF_ELIMIT, ptr, "more than %d points", CONTOUR_MAX_POINTS);
                break;
            }
            struct contour_slice *s = &out_roi->cs.s[out_roi->cs.n_slices++];
            s->src = (int)k;
            s->src_contour = -1;
            s->p = (double(*)[2])malloc(sizeof *s->p * np);
            if (!s->p) {
                rc = sf_fail(err, SF_ENOMEM, "", "out of memory");
                break;
            }
            s->n = (int)np;
            /* the raw value, parsed once: getFloat64(pos) re-scans the string for every position */
            char *raw = NULL;
            if (el->getString(raw).bad() || !raw) {
                rc = sf_fail(err, SF_EINVAL, ptr, "ContourData could not be read");
                break;
            }
            const char *p = raw;
            double z0 = 0;
            for (unsigned long i = 0; i < np && !rc; i++) {
                double v[3];
                for (int d = 0; d < 3 && !rc; d++) {
                    char *end;
                    v[d] = strtod(p, &end);
                    if (end == p || !std::isfinite(v[d]))
                        rc = sf_fail(err, SF_EINVAL, ptr, "point %lu is not three finite numbers", i);
                    else if (std::fabs(v[d]) > RTSTRUCT_MAX_COORD)
                        rc = sf_fail(err, SF_EINVAL, ptr, "point %lu has a coordinate of %.6g mm: surfd reads up to %g mm "
                                     "from the origin", i, v[d], RTSTRUCT_MAX_COORD);
                    p = end;
                    while (*p == ' ')
                        p++;
                    if (*p == '\\')
                        p++;
                }
                if (rc)
                    break;
                if (i == 0)
                    z0 = v[2];
                else if (std::fabs(v[2] - z0) > PLANAR_EPS) {
                    rc = sf_fail(err, SF_EINVAL, ptr, "a CLOSED_PLANAR contour must lie in one z plane");
                    break;
                }
                s->p[i][0] = v[0];
                s->p[i][1] = v[1];
            }
            s->z = z0;
            DcmItem *ref = NULL;
            OFString img;
            if (ci->findAndGetSequenceItem(DCM_ContourImageSequence, ref, 0).good() && ref &&
                ref->findAndGetOFString(DCM_ReferencedSOPInstanceUID, img).good())
                image_z[img.c_str()] = z0;
        }
        if (!rc && out_roi->cs.n_slices == 0) { // only non-planar kinds: nothing to model, listed
            contour_set_free(&out_roi->cs);
            out_roi->skipped = "only POINT or OPEN contours, which bound no volume";
        }
    }
    for (std::map<long, std::string>::const_iterator it = names.begin(); !rc && it != names.end(); ++it) {
        rois[n].number = (int)it->first;
        snprintf(rois[n].name, sizeof rois[n].name, "%s", it->second.c_str());
        rois[n++].skipped = "no contours (no ROI Contour item)";
    }
    struct rt_image *images = NULL;
    int n_images = 0;
    if (!rc && !image_items.empty() && !(images = (struct rt_image *)calloc(image_items.size(), sizeof *images)))
        rc = sf_fail(err, SF_ENOMEM, "", "out of memory");
    for (size_t k = 0; !rc && k < image_items.size(); k++) {
        OFString cls, inst;
        if (image_items[k]->findAndGetOFString(DCM_ReferencedSOPClassUID, cls).bad() ||
            image_items[k]->findAndGetOFString(DCM_ReferencedSOPInstanceUID, inst).bad() || cls.size() > 64 || inst.size() > 64)
            continue; // not a reference an export can repeat
        struct rt_image *im = &images[n_images++];
        snprintf(im->sop_class, sizeof im->sop_class, "%s", cls.c_str());
        snprintf(im->sop_instance, sizeof im->sop_instance, "%s", inst.c_str());
        im->z = image_z.count(inst.c_str()) ? image_z[inst.c_str()] : NAN;
    }
    for (int k = 0; !rc && k < n && n_images > 0; k++) {
        rois[k].images = images;
        rois[k].n_images = n_images;
        snprintf(rois[k].series_uid, sizeof rois[k].series_uid, "%s", series.c_str());
    }
    if (rc || n == 0 || n_images == 0)
        free(images); // unless the ROIs hold it
    if (rc) {
        rtstruct_free(rois, n);
        return rc;
    }
    *out = rois;
    *n_out = n;
    return 0;
}

/* ---- a model's sections as an RT Structure Set ------------------------------------------------ */

/* The image of the series in plane z (within PLANAR_EPS), or NULL. */
static const struct rt_image *image_at(const struct rt_export *e, double z)
{
    for (int k = 0; k < e->n_images; k++)
        if (std::fabs(e->images[k].z - z) <= PLANAR_EPS)
            return &e->images[k];
    return NULL;
}

extern "C" int rtstruct_write(const struct rt_export *e, unsigned char **out, size_t *out_len, struct sf_err *err)
{
    *out = NULL;
    *out_len = 0;
    DcmFileFormat ff;
    DcmDataset *ds = ff.getDataset();
    char sop[100], series[100], study[100], frame[100], date[16], tm[16];
    dcm_uid(sop, NULL, SITE_INSTANCE_UID_ROOT);
    dcm_uid(series, NULL, SITE_SERIES_UID_ROOT);
    dcm_uid(study, e->study_uid, SITE_STUDY_UID_ROOT);
    dcm_uid(frame, e->frame_uid, SITE_INSTANCE_UID_ROOT);
    dcm_now(date, tm);
    /* the modules of the RT Structure Set IOD; the patient's and the study's type 2 elements empty:
     * a request carries no patient data, and none is made up */
    static const DcmTagKey EMPTY[] = {DCM_PatientName, DCM_PatientID, DCM_PatientBirthDate, DCM_PatientSex,
                                      DCM_StudyDate, DCM_StudyTime, DCM_ReferringPhysicianName, DCM_StudyID,
                                      DCM_AccessionNumber, DCM_OperatorsName};
    bool ok = ds->putAndInsertString(DCM_SpecificCharacterSet, "ISO_IR 192").good() &&
              ds->putAndInsertString(DCM_SOPClassUID, RT_STRUCT_SOP_CLASS).good() &&
              ds->putAndInsertString(DCM_SOPInstanceUID, sop).good() &&
              ds->putAndInsertString(DCM_StudyInstanceUID, study).good() &&
              ds->putAndInsertString(DCM_SeriesInstanceUID, series).good() &&
              ds->putAndInsertString(DCM_Modality, "RTSTRUCT").good() &&
              ds->putAndInsertString(DCM_SeriesNumber, "1").good() &&
              ds->putAndInsertString(DCM_InstanceNumber, "1").good() &&
              ds->putAndInsertString(DCM_Manufacturer, "surfd").good() &&
              ds->putAndInsertString(DCM_StructureSetLabel, e->label && *e->label ? e->label : "surfd").good() &&
              ds->putAndInsertString(DCM_StructureSetDate, date).good() &&
              ds->putAndInsertString(DCM_StructureSetTime, tm).good() &&
              ds->putAndInsertString(DCM_InstanceCreationDate, date).good() &&
              ds->putAndInsertString(DCM_InstanceCreationTime, tm).good() &&
              ds->putAndInsertString(DCM_FrameOfReferenceUID, frame).good() &&
              ds->insertEmptyElement(DCM_PositionReferenceIndicator).good();
    for (size_t k = 0; ok && k < sizeof EMPTY / sizeof *EMPTY; k++)
        ok = ds->insertEmptyElement(EMPTY[k]).good();
    /* the frame, and through the study the series' images (each of its type 1 levels needs the
     * next: without images, no study is referenced) */
    DcmItem *it = NULL, *st = NULL, *se = NULL;
    ok = ok && ds->findOrCreateSequenceItem(DCM_ReferencedFrameOfReferenceSequence, it, -2).good() &&
         it->putAndInsertString(DCM_FrameOfReferenceUID, frame).good();
    if (ok && e->n_images > 0 && e->series_uid && *e->series_uid)
        ok = it->findOrCreateSequenceItem(DCM_RTReferencedStudySequence, st, -2).good() &&
             st->putAndInsertString(DCM_ReferencedSOPClassUID, "1.2.840.10008.3.1.2.3.1").good() && /* Study Component Management (detached study) */
             st->putAndInsertString(DCM_ReferencedSOPInstanceUID, study).good() &&
             st->findOrCreateSequenceItem(DCM_RTReferencedSeriesSequence, se, -2).good() &&
             se->putAndInsertString(DCM_SeriesInstanceUID, e->series_uid).good();
    for (int k = 0; ok && se && k < e->n_images; k++) {
        DcmItem *im = NULL;
        ok = se->findOrCreateSequenceItem(DCM_ContourImageSequence, im, -2).good() &&
             im->putAndInsertString(DCM_ReferencedSOPClassUID, e->images[k].sop_class).good() &&
             im->putAndInsertString(DCM_ReferencedSOPInstanceUID, e->images[k].sop_instance).good();
    }
    std::string data;
    for (int r = 0; ok && r < e->n_roi; r++) {
        const struct rt_export_roi *x = &e->roi[r];
        char num[16], rgb[48];
        snprintf(num, sizeof num, "%d", x->number);
        snprintf(rgb, sizeof rgb, "%d\\%d\\%d", x->color[0], x->color[1], x->color[2]);
        ok = ds->findOrCreateSequenceItem(DCM_StructureSetROISequence, it, -2).good() &&
             it->putAndInsertString(DCM_ROINumber, num).good() &&
             it->putAndInsertString(DCM_ReferencedFrameOfReferenceUID, frame).good() &&
             it->putAndInsertString(DCM_ROIName, x->name).good() &&
             it->putAndInsertString(DCM_ROIGenerationAlgorithm, "AUTOMATIC").good() &&
             it->putAndInsertString(DCM_ROIGenerationDescription, "surfd").good();
        ok = ok && ds->findOrCreateSequenceItem(DCM_RTROIObservationsSequence, it, -2).good() &&
             it->putAndInsertString(DCM_ObservationNumber, num).good() &&
             it->putAndInsertString(DCM_ReferencedROINumber, num).good() &&
             it->putAndInsertString(DCM_RTROIInterpretedType, x->type).good() && it->insertEmptyElement(DCM_ROIInterpreter).good();
        DcmItem *roi = NULL;
        ok = ok && ds->findOrCreateSequenceItem(DCM_ROIContourSequence, roi, -2).good() &&
             roi->putAndInsertString(DCM_ReferencedROINumber, num).good() &&
             roi->putAndInsertString(DCM_ROIDisplayColor, rgb).good();
        for (int c = 0; ok && c < x->n; c++) {
            const struct rt_contour *k = &x->c[c];
            DcmItem *ci = NULL, *im = NULL;
            char n[16], cn[16];
            snprintf(n, sizeof n, "%d", k->n);
            snprintf(cn, sizeof cn, "%d", c + 1);
            data.clear();
            for (int i = 0; i < k->n; i++)
                for (int d3 = 0; d3 < 3; d3++) {
                    /* DS: 16 characters at most, with as many digits as fit (15 hold a 1e-6 mm grid
                     * exactly up to a kilometre: the coordinates keyhole_join tested are those read) */
                    char v[32];
                    for (int prec = 15; prec >= 6; prec--)
                        if (snprintf(v, sizeof v, "%.*g", prec, k->p[i][d3]) <= 16)
                            break;
                    if (!data.empty())
                        data += "\\";
                    data += v;
                }
            const struct rt_image *img = se && k->n > 0 ? image_at(e, k->p[0][2]) : NULL;
            ok = roi->findOrCreateSequenceItem(DCM_ContourSequence, ci, -2).good() &&
                 ci->putAndInsertString(DCM_ContourNumber, cn).good() &&
                 (!img || (ci->findOrCreateSequenceItem(DCM_ContourImageSequence, im, -2).good() &&
                           im->putAndInsertString(DCM_ReferencedSOPClassUID, img->sop_class).good() &&
                           im->putAndInsertString(DCM_ReferencedSOPInstanceUID, img->sop_instance).good())) &&
                 ci->putAndInsertString(DCM_ContourGeometricType, "CLOSED_PLANAR").good() &&
                 ci->putAndInsertString(DCM_NumberOfContourPoints, n).good() &&
                 ci->putAndInsertString(DCM_ContourData, data.c_str()).good();
        }
    }
    if (!ok)
        return sf_fail(err, SF_ENOMEM, "", "out of memory making the structure set");
    return dcm_write_object(ff, out, out_len, "the structure set", err);
}
