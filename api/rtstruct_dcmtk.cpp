// rtstruct_dcmtk.cpp - DCMTK for RT Structure Sets (series_dcmtk.cpp reads image series): an RT
// Structure Set in memory to contour sets, and a model's sections back to one (rtstruct_write).
// ROI names come from StructureSetROISequence, contours from ROIContourSequence (CLOSED_PLANAR
// only; POINT and OPEN_* contours are skipped, as they bound nothing). Slice z is the contour's
// own z (ContourData is x, y, z triples in patient coordinates); a contour whose z varies is not
// planar and is refused. No other element of the object is read.
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

/* Copies the elements tags (where present) from one item to another; false when out of memory. */
static bool copy_elements(DcmItem *from, DcmItem *to, const DcmTagKey *tags, size_t n)
{
    for (size_t k = 0; k < n; k++) {
        DcmElement *el = NULL;
        if (from->findAndGetElement(tags[k], el).good() && el &&
            to->insert(static_cast<DcmElement *>(el->clone())).bad())
            return false;
    }
    return true;
}

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
    OFString study;
    ds->findAndGetOFString(DCM_StudyInstanceUID, study);
    bool ok = kd->putAndInsertString(DCM_SOPClassUID, RT_STRUCT_SOP_CLASS).good() &&
              kd->putAndInsertString(DCM_SOPInstanceUID, dcmGenerateUniqueIdentifier(uid, SITE_INSTANCE_UID_ROOT)).good() &&
              kd->putAndInsertString(DCM_Modality, "RTSTRUCT").good() &&
              (study.empty() || kd->putAndInsertString(DCM_StudyInstanceUID, study.c_str()).good());
    static const DcmTagKey ROI_TAGS[] = {DCM_ROINumber, DCM_ROIName, DCM_ReferencedFrameOfReferenceUID};
    static const DcmTagKey CONTOUR_ROI_TAGS[] = {DCM_ReferencedROINumber, DCM_ROIDisplayColor};
    static const DcmTagKey CONTOUR_TAGS[] = {DCM_ContourGeometricType, DCM_NumberOfContourPoints, DCM_ContourData};
    DcmSequenceOfItems *seq = NULL;
    if (ok && ds->findAndGetSequence(DCM_StructureSetROISequence, seq).good() && seq)
        for (DcmItem *src : items_of(seq)) {
            DcmItem *item = NULL;
            ok = ok && kd->findOrCreateSequenceItem(DCM_StructureSetROISequence, item, -2).good() &&
                 copy_elements(src, item, ROI_TAGS, 3);
        }
    seq = NULL;
    bool contours = ok && ds->findAndGetSequence(DCM_ROIContourSequence, seq).good() && seq;
    if (contours && seq->card() == 0) /* kept, empty: its ROIs read as skipped, as they were */
        ok = kd->insert(new DcmSequenceOfItems(DCM_ROIContourSequence)).good();
    if (contours)
        for (DcmItem *roi : items_of(seq)) {
            DcmItem *item = NULL;
            ok = ok && kd->findOrCreateSequenceItem(DCM_ROIContourSequence, item, -2).good() &&
                 copy_elements(roi, item, CONTOUR_ROI_TAGS, 2);
            DcmSequenceOfItems *cseq = NULL;
            if (ok && roi->findAndGetSequence(DCM_ContourSequence, cseq).good() && cseq)
                for (DcmItem *src : items_of(cseq)) {
                    DcmItem *c = NULL;
                    ok = ok && item->findOrCreateSequenceItem(DCM_ContourSequence, c, -2).good() &&
                         copy_elements(src, c, CONTOUR_TAGS, 3);
                }
        }
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
    if (rc) {
        rtstruct_free(rois, n);
        return rc;
    }
    *out = rois;
    *n_out = n;
    return 0;
}

/* ---- a model's sections as an RT Structure Set ------------------------------------------------ */

extern "C" int rtstruct_write(const struct rt_export *e, unsigned char **out, size_t *out_len, struct sf_err *err)
{
    *out = NULL;
    *out_len = 0;
    DcmFileFormat ff;
    DcmDataset *ds = ff.getDataset();
    char sop[100], series[100], study[100], frame[100], date[16], tm[16], num[16];
    dcm_uid(sop, NULL, SITE_INSTANCE_UID_ROOT);
    dcm_uid(series, NULL, SITE_SERIES_UID_ROOT);
    dcm_uid(study, e->study_uid, SITE_STUDY_UID_ROOT);
    dcm_uid(frame, e->frame_uid, SITE_INSTANCE_UID_ROOT);
    dcm_now(date, tm);
    snprintf(num, sizeof num, "%d", e->roi_number);
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
    DcmItem *it = NULL;
    ok = ok && ds->findOrCreateSequenceItem(DCM_ReferencedFrameOfReferenceSequence, it, -2).good() &&
         it->putAndInsertString(DCM_FrameOfReferenceUID, frame).good();
    ok = ok && ds->findOrCreateSequenceItem(DCM_StructureSetROISequence, it, -2).good() &&
         it->putAndInsertString(DCM_ROINumber, num).good() &&
         it->putAndInsertString(DCM_ReferencedFrameOfReferenceUID, frame).good() &&
         it->putAndInsertString(DCM_ROIName, e->roi_name).good() &&
         it->putAndInsertString(DCM_ROIGenerationAlgorithm, "SEMIAUTOMATIC").good();
    ok = ok && ds->findOrCreateSequenceItem(DCM_RTROIObservationsSequence, it, -2).good() &&
         it->putAndInsertString(DCM_ObservationNumber, num).good() &&
         it->putAndInsertString(DCM_ReferencedROINumber, num).good() &&
         it->insertEmptyElement(DCM_RTROIInterpretedType).good() && it->insertEmptyElement(DCM_ROIInterpreter).good();
    DcmItem *roi = NULL;
    ok = ok && ds->findOrCreateSequenceItem(DCM_ROIContourSequence, roi, -2).good() &&
         roi->putAndInsertString(DCM_ReferencedROINumber, num).good() &&
         roi->putAndInsertString(DCM_ROIDisplayColor, "255\\128\\0").good();
    std::string data;
    for (int c = 0; ok && c < e->n; c++) {
        const struct rt_contour *k = &e->c[c];
        DcmItem *ci = NULL;
        char n[16], cn[16];
        snprintf(n, sizeof n, "%d", k->n);
        snprintf(cn, sizeof cn, "%d", c + 1);
        data.clear();
        for (int i = 0; i < k->n; i++)
            for (int d3 = 0; d3 < 3; d3++) {
                char v[32];
                snprintf(v, sizeof v, "%s%.9g", data.empty() ? "" : "\\", k->p[i][d3]); /* DS: 16 characters at most */
                data += v;
            }
        ok = roi->findOrCreateSequenceItem(DCM_ContourSequence, ci, -2).good() &&
             ci->putAndInsertString(DCM_ContourNumber, cn).good() &&
             ci->putAndInsertString(DCM_ContourGeometricType, "CLOSED_PLANAR").good() &&
             ci->putAndInsertString(DCM_NumberOfContourPoints, n).good() &&
             ci->putAndInsertString(DCM_ContourData, data.c_str()).good();
    }
    if (!ok)
        return sf_fail(err, SF_ENOMEM, "", "out of memory making the structure set");
    return dcm_write_object(ff, out, out_len, "the structure set", err);
}
