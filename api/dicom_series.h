/* dicom_series.h - a CT or MR series posted as multipart/form-data, one DICOM image a part, to
 * one volume: through DCMTK behind series_dcmtk.cpp. Slices are sorted by ImagePositionPatient
 * along the slice normal (never by part or file name); Rescale Slope and Intercept are applied;
 * the slice spacing comes from the positions, and a series whose spacing is uneven (a missing
 * slice, two series mixed) is refused, not resampled. Only the geometry and pixel elements are
 * read: no patient element is read, logged or echoed. */
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

struct series {
    struct iso_grid g;       /* spacing: columns, rows, slices (mm); origin: the first slice's position */
    void *owned;             /* the samples (NULL with check_only) */
    double axes[3][3];       /* the grid's x, y, z directions in patient coordinates (row, column, normal) */
};

/* Reads n parts as one series. check_only: the headers alone (the pixel data is neither read nor
 * checked). Errors name the part ("/parts/3"): SF_EFORMAT for a part that is not DICOM, SF_EINVAL
 * for one that does not fit the others (size, orientation, spacing, a position already taken, a
 * missing slice) or is compressed, SF_ELIMIT past VOLUME_MAX_SAMPLES-like limits (max_samples). */
int series_read(const struct part *parts, int n, bool check_only, size_t max_samples, struct series *out,
                struct sf_err *err);

#ifdef __cplusplus
}
#endif

#endif
