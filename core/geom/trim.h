/* trim.h - the trimmed region of a surface's parameter domain: closed loops in (u, v), as
 * polylines, and the region they bound by the even-odd rule (an IGES 144's outer loop and its
 * holes, or a 143's boundaries, whichever way round each runs). A uniform grid over the loops'
 * bounds keeps, per cell, the segments that touch it and whether its centre is inside, so a
 * point is classified by crossing only its cell's segments (on the stretch from the point to
 * the centre) and a box as wholly inside, wholly outside or cut by a loop.
 *
 * Written here: the tracer asks this once per hit in a cut leaf, so it must be a lookup, and
 * no Debian library offers a point-in-polygon index over (u, v) loops. */
#ifndef SURFD_TRIM_H
#define SURFD_TRIM_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "../base/err.h"

#define TRIM_MAX_POINTS (1u << 22) /* loop points per surface: caps memory per request */
#define TRIM_GRID_MAX 512          /* cells per side of the index */
#define TRIM_MAX_ENTRIES (1u << 25) /* segment-in-cell entries of the index */

enum trim_class { TRIM_OUT, TRIM_IN, TRIM_CUT };

struct trim {
    size_t n_pts;         /* all loops' points, loop after loop, each closed (its first point repeated) */
    double (*pt)[2];
    int n_loops;
    size_t *start;        /* n_loops + 1 offsets into pt */
    /* the index */
    double u0, v0, du, dv; /* the grid's origin and cell size */
    int gu, gv;
    uint32_t *cell_first; /* gu * gv + 1 offsets into cell_seg */
    uint32_t *cell_seg;   /* segment k: from pt[k] to the next point of its loop */
    uint8_t *cell_in;     /* 1 where the cell's centre is inside */
};

/* Takes loops (n_loops of them; loop k has counts[k] >= 3 points at pts[...], consecutive) and
 * builds the index. The loops are copied. Returns 0, SF_ENOMEM, SF_ECANCEL (pr, polled as the
 * segments are binned, asked to stop; NULL: never), or SF_ELIMIT / SF_EINVAL (too many points, a
 * loop of fewer than 3, a coordinate not finite) with err's pointer where. */
int trim_build(struct trim *t, const double (*pts)[2], const size_t *counts, int n_loops, const char *where,
               const struct sf_progress *pr, struct sf_err *err);
void trim_free(struct trim *t);

bool trim_contains(const struct trim *t, double u, double v);
/* Where the box [u0, u1] x [v0, v1] lies: inside or outside every loop, or cut by one. */
enum trim_class trim_classify(const struct trim *t, double u0, double u1, double v0, double v1);

/* The area in (u, v) of the region's part within the box (exact for the loops' polylines: Green's
 * theorem round that part's boundary), and its centroid; -1 when more loop segments meet the box
 * than one call takes (split the box). */
double trim_box_moments(const struct trim *t, double u0, double u1, double v0, double v1, double centroid[2]);

#endif
