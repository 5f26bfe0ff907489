/* rtstruct.h - DICOM RT Structure Sets to contour sets, through DCMTK behind rtstruct_dcmtk.cpp.
 * Only ROI names and numbers and CLOSED_PLANAR contour data are read: patient data is never read,
 * logged or echoed. The caller frees with rtstruct_free(). */
#ifndef SURFD_RTSTRUCT_H
#define SURFD_RTSTRUCT_H

#include <stddef.h>

#ifdef __cplusplus
extern "C" { /* the C headers below declare C functions */
#endif

#include "../core/contour/contour.h"
#include "../core/base/err.h"

#define RTSTRUCT_MAX_ROIS 1000

struct rt_roi {
    char name[128];
    int number;              /* ROI Number */
    struct contour_set cs;   /* uncleaned: contour_clean() is the caller's */
    const char *skipped;     /* NULL; or why the ROI has nothing to model (cs empty): listed, not built */
    char frame_uid[65];      /* its Referenced Frame of Reference UID, "" when absent */
    char study_uid[65];      /* the structure set's Study Instance UID, "" when absent */
};

/* Reads every ROI: those with closed planar contours, and those without (skipped set). SF_EFORMAT for what is not DICOM, SF_EINVAL for a DICOM
 * object that is not an RT Structure Set or holds malformed contours (pointer: the DICOM path,
 * e.g. "/ROIContourSequence/2/ContourSequence/7/ContourData"). */
int rtstruct_read(const void *buf, size_t len, struct rt_roi **rois, int *n_rois, struct sf_err *err);
void rtstruct_free(struct rt_roi *rois, int n_rois);

/* A copy of the structure set with only what rtstruct_read reads (SOP class, ROI numbers, names
 * and frame of reference, contour types, points and data, ROI colours, the study's UID) and a fresh
 * instance UID:
 * no patient, study, series, equipment or personnel modules, no image references. For storing
 * what a request needs to be run again. *out (caller frees) and *out_len receive a DICOM Part 10
 * object; the Study Instance UID is kept too (a link, not patient data: exports reference it).
 * Errors as rtstruct_read. */
int rtstruct_strip(const void *buf, size_t len, unsigned char **out, size_t *out_len, struct sf_err *err);

/* One structure as an RT Structure Set: its closed planar contours (x, y, z in patient
 * coordinates, mm), referencing study_uid and frame_uid (NULL or "": fresh ones). The patient's
 * and study's type 2 elements are present and empty: nothing the request did not carry. */
struct rt_contour {
    double (*p)[3];
    int n;
};
struct rt_export {
    const char *label, *roi_name;
    int roi_number;
    const char *study_uid, *frame_uid;
    const struct rt_contour *c;
    int n;
};
int rtstruct_write(const struct rt_export *e, unsigned char **out, size_t *out_len, struct sf_err *err);

#ifdef __cplusplus
}
#endif

#endif
