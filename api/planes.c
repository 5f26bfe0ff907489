/* planes.c - a stack of image planes to one grid (planes.h): the series' rules (one size,
 * orientation and spacing; sorted along the normal; even spacing, within 1 % or 0.01 mm) written
 * once for a series' slices and a multi-frame image's frames, and the sparse stack of a
 * Segmentation's frames. It never resamples: planes that do not fit are refused by name. */
#include "planes.h"

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>

#include "ranges.h"

void planes_where(int part, long frame, char *out, size_t cap)
{
    if (frame < 0)
        snprintf(out, cap, "/parts/%d", part);
    else
        snprintf(out, cap, "/parts/%d/frames/%ld", part, frame);
}

void planes_pointer(const struct plane *p, char *out, size_t cap)
{
    planes_where(p->part, p->frame, out, cap);
}

static int fail_plane(struct sf_err *err, int code, const struct plane *p, const char *what)
{
    char where[48];
    planes_pointer(p, where, sizeof where);
    return sf_fail(err, code, where, "%s", what);
}

static int by_place(const void *a, const void *b)
{
    const struct plane *p = a, *q = b;
    if (p->s != q->s)
        return p->s < q->s ? -1 : 1;
    return p->part != q->part ? (p->part < q->part ? -1 : 1) : (p->frame > q->frame) - (p->frame < q->frame);
}

/* Whether spacing is within ranges.h's range; else what says so into what. */
static bool spacing_in_range(double d, const char *word, char *what, size_t cap)
{
    if (d >= RANGE_MIN_SPACING && d <= RANGE_MAX_SPACING)
        return true;
    snprintf(what, cap, "ImagePositionPatient puts the %ss %.3g mm apart: surfd reads %g to %g mm", word, d,
             RANGE_MIN_SPACING, RANGE_MAX_SPACING);
    return false;
}

/* The even stack: every place one plane, each step within 1 % (or 0.01 mm) of the mean. */
static int lay_even(struct plane *pl, int n, const char *word, double *step, struct sf_err *err)
{
    char what[240];
    double mean = (pl[n - 1].s - pl[0].s) / (n - 1);
    if (!(mean > 0)) {
        snprintf(what, sizeof what, "two %ss at the same position", word);
        return fail_plane(err, SF_EINVAL, &pl[1], what);
    }
    if (mean < RANGE_MIN_SPACING || mean > RANGE_MAX_SPACING) {
        snprintf(what, sizeof what, "ImagePositionPatient puts the %ss %.3g mm apart on average: surfd reads %g to "
                 "%g mm", word, mean, RANGE_MIN_SPACING, RANGE_MAX_SPACING);
        return fail_plane(err, SF_EINVAL, &pl[n - 1], what);
    }
    for (int k = 1; k < n; k++) {
        double d = pl[k].s - pl[k - 1].s;
        if (d <= 0) {
            snprintf(what, sizeof what, "two %ss at the same position", word);
            return fail_plane(err, SF_EINVAL, &pl[k], what);
        }
        if (fabs(d - mean) > fmax(0.01, 0.01 * mean)) {
            snprintf(what, sizeof what, "%.3g mm from the %s before it, %.3g mm on average: a %s is missing or the "
                     "%ss are not one %s (surfd does not resample uneven spacing)", d, word, mean, word,
                     pl[k].frame < 0 ? "part" : word, pl[k].frame < 0 ? "series" : "stack");
            return fail_plane(err, SF_EINVAL, &pl[k], what);
        }
    }
    for (int k = 0; k < n; k++)
        pl[k].z = k;
    *step = mean;
    return 0;
}

/* The sparse stack: places within PLANES_SAME_EPS are one; the step is the least distance between
 * two places, and every place a whole number of steps from the first. */
static int lay_sparse(struct plane *pl, int n, size_t plane_samples, size_t max_samples, double *step, int *nz,
                      struct sf_err *err)
{
    char what[240];
    double least = INFINITY;
    for (int k = 1; k < n; k++) {
        double d = pl[k].s - pl[k - 1].s;
        if (d > PLANES_SAME_EPS && d < least)
            least = d;
    }
    if (!isfinite(least))
        return fail_plane(err, SF_EINVAL, &pl[0], "every frame lies in one plane: a volume is at least 2 planes");
    if (!spacing_in_range(least, "frame", what, sizeof what))
        return fail_plane(err, SF_EINVAL, &pl[n - 1], what);
    double span = (pl[n - 1].s - pl[0].s) / least;
    /* the grid's size before anything is allocated: the places may lie far apart */
    if (span + 1 > (double)max_samples / (double)plane_samples) {
        snprintf(what, sizeof what, "the frames span %.0f planes %.3g mm apart: over %zu samples", floor(span + 1.5),
                 least, max_samples);
        return fail_plane(err, SF_ELIMIT, &pl[n - 1], what);
    }
    for (int k = 0; k < n; k++) {
        double at = (pl[k].s - pl[0].s) / least, whole = floor(at + 0.5);
        if (fabs(at - whole) * least > fmax(PLANES_SAME_EPS, 0.01 * least)) {
            snprintf(what, sizeof what, "%.4g mm from the first frame: not a whole number of the frames' least "
                     "distance apart (%.4g mm), so not on one grid (surfd does not resample)", pl[k].s - pl[0].s, least);
            return fail_plane(err, SF_EINVAL, &pl[k], what);
        }
        pl[k].z = (int)whole;
    }
    *step = least;
    *nz = pl[n - 1].z + 1;
    return 0;
}

int planes_layout(struct plane *pl, int n, bool sparse, size_t max_samples, struct planes_grid *g, struct sf_err *err)
{
    if (n < 1)
        return sf_fail(err, SF_EINVAL, "/parts", "no image planes");
    const struct plane a = pl[0];
    const char *word = a.frame < 0 ? "slice" : "frame";
    char what[160];
    double r[3] = {a.orient[0], a.orient[1], a.orient[2]}, c[3] = {a.orient[3], a.orient[4], a.orient[5]};
    double nrm[3] = {r[1] * c[2] - r[2] * c[1], r[2] * c[0] - r[0] * c[2], r[0] * c[1] - r[1] * c[0]};
    double len = sqrt(nrm[0] * nrm[0] + nrm[1] * nrm[1] + nrm[2] * nrm[2]);
    if (!(len > 0.99 && len < 1.01))
        return fail_plane(err, SF_EINVAL, &a, "ImageOrientationPatient is not two unit, perpendicular directions");
    for (int k = 0; k < n; k++) {
        struct plane *p = &pl[k];
        if (p->rows != a.rows || p->cols != a.cols) {
            snprintf(what, sizeof what, "a %s of another size than the first %s's", word, a.frame < 0 ? "part" : word);
            return fail_plane(err, SF_EINVAL, p, what);
        }
        for (int i = 0; i < 6; i++)
            if (fabs(p->orient[i] - a.orient[i]) > 1e-4) {
                snprintf(what, sizeof what, "a %s of another orientation than the first %s's", word,
                         a.frame < 0 ? "part" : word);
                return fail_plane(err, SF_EINVAL, p, what);
            }
        for (int i = 0; i < 2; i++)
            if (fabs(p->spacing[i] - a.spacing[i]) > 1e-4 * a.spacing[i]) {
                snprintf(what, sizeof what, "a %s of another PixelSpacing than the first %s's", word,
                         a.frame < 0 ? "part" : word);
                return fail_plane(err, SF_EINVAL, p, what);
            }
        p->s = (p->pos[0] * nrm[0] + p->pos[1] * nrm[1] + p->pos[2] * nrm[2]) / len;
    }
    qsort(pl, (size_t)n, sizeof *pl, by_place);
    double step = 0;
    int nz = n, rc;
    if (n < 2 && !sparse)
        return fail_plane(err, SF_EINVAL, &pl[0], "one plane: a volume is at least 2");
    rc = sparse ? lay_sparse(pl, n, (size_t)a.rows * a.cols, max_samples, &step, &nz, err)
                : lay_even(pl, n, word, &step, err);
    if (rc)
        return rc;
    g->nx = (int)a.cols, g->ny = (int)a.rows, g->nz = nz;
    g->spacing[0] = a.spacing[1]; /* PixelSpacing is row spacing \ column spacing */
    g->spacing[1] = a.spacing[0];
    g->spacing[2] = step;
    for (int i = 0; i < 3; i++) {
        g->origin[i] = pl[0].pos[i];
        g->axes[0][i] = r[i], g->axes[1][i] = c[i], g->axes[2][i] = nrm[i] / len;
    }
    return 0;
}
