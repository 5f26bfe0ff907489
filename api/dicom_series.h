/* dicom_series.h - DICOM images to one volume, through DCMTK: a CT or MR series posted as
 * multipart/form-data, one image a part (series_dcmtk.cpp), or one multi-frame image, posted as the
 * body or as a one-part series (frames_dcmtk.cpp): an Enhanced CT or MR image (each frame placed by
 * its functional groups), an RT Dose (GridFrameOffsetVector; DoseGridScaling applied: Gy) or a
 * Segmentation (one segment: 0 and 1, or its fractions scaled to 0..1; or, as a label map, every
 * segment's SegmentNumber where its frames hold it: binary 1, fractional over half). Slices and frames are sorted
 * along the normal of their orientation (never by part, file name or frame number); Rescale Slope
 * and Intercept are applied; the slice spacing comes from the positions, and a stack whose spacing
 * is uneven (a missing slice, two series mixed) is refused, not resampled (planes.h). Only the
 * geometry, value and pixel elements are read: no patient element is read, logged or echoed. */
#ifndef SURFD_DICOM_SERIES_H
#define SURFD_DICOM_SERIES_H

#include <stdbool.h>
#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

#include "../core/base/err.h"
#include "../core/iso/mc.h"
#include "multipart.h"

/* A Segmentation's segment read as a label map's label. */
struct series_segment {
    unsigned number;         /* its SegmentNumber: the label */
    char label[64];          /* its SegmentLabel, printable ASCII */
};

struct series {
    struct iso_grid g;       /* spacing: columns, rows, slices (mm); origin: the first slice's position */
    void *owned;             /* the samples (NULL with check_only) */
    bool typed;              /* with check_only: g.type is what the samples will be (a Segmentation's); else
                              * int16 or float32 is decided by their values */
    double axes[3][3];       /* the grid's x, y, z directions in patient coordinates (row, column, normal) */
    /* as_labels, a Segmentation: g is a uint16 label map of SegmentNumbers (0 none), and these its
     * segments (number, SegmentLabel; malloc'ed, the caller frees); else label_map is false */
    bool label_map;
    struct series_segment *segments;
    int n_segments;
    /* a series of single-frame images: its first slice's UIDs (what an export of its models
     * references: a SEG's grid is the series' when it is stored), "" when absent or not UIDs */
    char series_uid[65], study_uid[65], frame_uid[65];
};

/* Reads n parts as one series, or one part that is a multi-frame image. check_only: the headers
 * alone (the pixel data is neither read nor checked, but its length is). segment: a Segmentation's
 * segment (its SegmentNumber), 0 when ?segment was not given (then a Segmentation of several
 * segments is refused, naming them). as_labels: a Segmentation is read as a label map (segment 0:
 * every segment, where two overlap refused naming them and the frame; else that one alone); other
 * images are read as without it, label_map false. Errors name the part ("/parts/3") or the frame
 * ("/parts/0/frames/12", frames counted from 0) or "?segment": SF_EFORMAT for a part that is not
 * DICOM, SF_EINVAL for one that does not fit the others (size, orientation, spacing, a position
 * already taken, a missing slice), is compressed other than surfd decodes, or whose frames do not
 * decode; SF_ELIMIT past max_samples (said before anything is decoded or allocated). */
int series_read(const struct part *parts, int n, bool check_only, size_t max_samples, int segment, bool as_labels,
                struct series *out, struct sf_err *err);

#ifdef __cplusplus
}
#endif

#endif
