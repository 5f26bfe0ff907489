/* rtstruct.h - DICOM RT Structure Sets to contour sets and back, through DCMTK behind
 * rtstruct_dcmtk.cpp. Read: ROI names, numbers, colours and interpreted types, CLOSED_PLANAR
 * contour data, and the UIDs that link them to their images (study, series, frame of reference,
 * images): patient data is never read, logged or echoed. The caller frees with rtstruct_free(). */
#ifndef SURFD_RTSTRUCT_H
#define SURFD_RTSTRUCT_H

#include <stddef.h>

#ifdef __cplusplus
extern "C" { /* the C headers below declare C functions */
#endif

#include "../core/contour/contour.h"
#include "../core/base/err.h"

#define RTSTRUCT_MAX_ROIS 1000
/* images of the referenced series kept (the ContourImageSequence an export repeats): a CT series
 * has a few hundred; past it none is kept, and exports reference no series */
#define RTSTRUCT_MAX_IMAGES 4096

struct rt_image {            /* an image the structure set references */
    char sop_class[65], sop_instance[65];
    double z;                /* the plane of the contours that reference it; NAN when none does */
};

struct rt_roi {
    char name[128];
    int number;              /* ROI Number */
    struct contour_set cs;   /* uncleaned: contour_clean() is the caller's */
    const char *skipped;     /* NULL; or why the ROI has nothing to model (cs empty): listed, not built */
    char frame_uid[65];      /* its Referenced Frame of Reference UID, "" when absent */
    char study_uid[65];      /* the structure set's Study Instance UID, "" when absent */
    char series_uid[65];     /* the series its images are in (RTReferencedSeriesSequence), "" when absent */
    int color[3];            /* ROIDisplayColor; -1s when absent */
    char type[17];           /* RTROIInterpretedType (RTROIObservationsSequence), "" when absent */
    const struct rt_image *images; /* the series' images, shared by every ROI of the set (freed with it) */
    int n_images;
};

/* Reads every ROI: those with closed planar contours, and those without (skipped set). SF_EFORMAT for what is not DICOM, SF_EINVAL for a DICOM
 * object that is not an RT Structure Set or holds malformed contours (pointer: the DICOM path,
 * e.g. "/ROIContourSequence/2/ContourSequence/7/ContourData"). */
int rtstruct_read(const void *buf, size_t len, struct rt_roi **rois, int *n_rois, struct sf_err *err);
void rtstruct_free(struct rt_roi *rois, int n_rois);

/* A copy of the structure set with only what rtstruct_read reads (SOP class, ROI numbers, names
 * and frame of reference, contour types, points and data, ROI colours and interpreted types, the
 * UIDs of the study, the referenced series and images) and a fresh instance UID: no patient,
 * equipment or personnel modules, no dates, descriptions or observers. For storing what a request
 * needs to be run again. *out (caller frees) and *out_len receive a DICOM Part 10 object; the UIDs
 * are links, not patient data: exports reference them. Errors as rtstruct_read. */
int rtstruct_strip(const void *buf, size_t len, unsigned char **out, size_t *out_len, struct sf_err *err);

/* Structures as one RT Structure Set: each ROI's closed planar contours (x, y, z in patient
 * coordinates, mm), its colour and interpreted type, all in one frame of reference and study
 * (NULL or "": fresh UIDs), referencing the series' images where given (RTReferencedSeriesSequence,
 * and each contour the image in its plane). The patient's and study's type 2 elements are
 * present and empty: nothing the request did not carry. */
struct rt_contour {
    double (*p)[3];
    int n;
};
struct rt_export_roi {
    const char *name;
    int number;                 /* 1..n */
    int color[3];
    const char *type;           /* RTROIInterpretedType */
    const struct rt_contour *c;
    int n;
};
struct rt_export {
    const char *label;
    const char *study_uid, *frame_uid, *series_uid;
    const struct rt_image *images; /* of series_uid; n_images 0: no series referenced */
    int n_images;
    const struct rt_export_roi *roi;
    int n_roi;
};
int rtstruct_write(const struct rt_export *e, unsigned char **out, size_t *out_len, struct sf_err *err);

#ifdef __cplusplus
}
#endif

#endif
