/* planes.h - a stack of image planes to one sample grid: a DICOM series' slices, or the frames of
 * a multi-frame image (Enhanced CT/MR, RT Dose, Segmentation). Each plane's place along the normal
 * of its orientation (row x column) sorts it; all are of one size, orientation and PixelSpacing;
 * either evenly spaced, each at its own place (a series', an RT Dose's, an Enhanced image's: a
 * missing plane refused, never resampled), or sparse (a Segmentation's frames, only where its
 * segments lie: on the grid of their least distance apart, the slices between left out). Geometry
 * alone, plain C: the DCMTK shims read the planes and fill the grid's samples. */
#ifndef SURFD_PLANES_H
#define SURFD_PLANES_H

#include <stdbool.h>
#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

#include "../core/base/err.h"

/* How far apart two planes may lie and still be one place of a sparse stack (mm): DS values keep
 * 16 characters, so real writers' positions for one plane agree far closer than this. */
#define PLANES_SAME_EPS 0.01

struct plane {
    int part;                /* the part it was read from: errors name "/parts/K" */
    int frame;               /* its frame there, -1 for a single-frame image: "/parts/K/frames/F" */
    unsigned rows, cols;
    double pos[3];           /* ImagePositionPatient: its first pixel's centre (mm) */
    double orient[6];        /* ImageOrientationPatient: the row and column directions */
    double spacing[2];       /* PixelSpacing: between rows, between columns (mm) */
    double s;                /* set by planes_layout: its place along the normal (mm) */
    int z;                   /* set by planes_layout: its slice of the grid */
    int tag;                 /* the caller's (which segment, which slot): kept through the sort */
};

struct planes_grid {
    int nx, ny, nz;
    double spacing[3];       /* columns, rows, slices (mm) */
    double origin[3];        /* the first slice's first pixel */
    double axes[3][3];       /* x, y, z in patient coordinates: the row direction, the column one, the normal */
};

/* The JSON pointer that names frame F of part K ("/parts/K/frames/F"; "/parts/K" when F < 0) into
 * out: what every refusal of a series' slice or a multi-frame image's frame is at. */
void planes_where(int part, long frame, char *out, size_t cap);
/* ... of plane p. */
void planes_pointer(const struct plane *p, char *out, size_t cap);

/* Lays the n planes of pl (sorted in place along the normal) out as one grid g, setting each
 * plane's s and z. sparse: planes may share a place (their z is then the same) and slices may be
 * missing between them; the slice spacing is the least distance between two places, and every
 * place must lie on that grid. Otherwise every place holds one plane, evenly spaced. 0, or SF_EINVAL
 * naming the plane that does not fit (another size, orientation or spacing than the first's, two
 * at one place, a missing slice, spacing out of ranges.h's range), SF_ELIMIT when the grid would
 * have over max_samples samples (said before anything is allocated). */
int planes_layout(struct plane *pl, int n, bool sparse, size_t max_samples, struct planes_grid *g, struct sf_err *err);

#ifdef __cplusplus
}
#endif

#endif
