/* raster.c - loops to a pixel mask by the even-odd rule (raster.h): a scanline fill whose
 * crossings are bucketed by row (each edge adds an x to the rows it spans, counted first, then
 * sorted per row), so a plane costs its crossings, not rows x edges. */
#include "raster.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* The rows edge a-b crosses: j with y_lo <= j < y_hi (half-open, so a vertex on a row is counted
 * once, by the edge that leaves it upwards), clamped to [0, rows). *j0 > *j1 when none. */
static void rows_of(const double *a, const double *b, int rows, long *j0, long *j1)
{
    double lo = fmin(a[1], b[1]), hi = fmax(a[1], b[1]);
    if (!(hi > lo) || hi <= 0 || lo >= rows) { /* horizontal, or off the grid (NaN too) */
        *j0 = 1, *j1 = 0;
        return;
    }
    *j0 = lo <= 0 ? 0 : (long)ceil(lo);
    *j1 = hi > rows ? rows - 1 : (long)ceil(hi) - 1;
}

int raster_loops(const struct trimesh_loops *l, int cols, int rows, unsigned char *mask, size_t *n_set,
                 struct sf_err *err)
{
    memset(mask, 0, (size_t)cols * (size_t)rows);
    if (n_set)
        *n_set = 0;
    long total = 0;
    for (int k = 0; k < l->n; k++) /* the count, before anything is allocated */
        for (int i = l->start[k]; i < l->start[k + 1]; i++) {
            int next = i + 1 < l->start[k + 1] ? i + 1 : l->start[k];
            long j0, j1;
            rows_of(l->p[i], l->p[next], rows, &j0, &j1);
            if (j1 >= j0 && (total += j1 - j0 + 1) > RASTER_MAX_CROSSINGS)
                return sf_fail(err, SF_ELIMIT, "", "a section crosses the grid's rows over %ld times",
                               RASTER_MAX_CROSSINGS);
        }
    if (total == 0)
        return 0;
    long *at = calloc((size_t)rows + 1, sizeof *at);
    double *x = malloc(sizeof *x * (size_t)total);
    if (!at || !x) {
        free(at);
        free(x);
        return sf_fail(err, SF_ENOMEM, "", "out of memory rasterising a section");
    }
    for (int pass = 0; pass < 2; pass++) { /* counts per row, then the crossings in their rows */
        for (int k = 0; k < l->n; k++)
            for (int i = l->start[k]; i < l->start[k + 1]; i++) {
                int next = i + 1 < l->start[k + 1] ? i + 1 : l->start[k];
                const double *a = l->p[i], *b = l->p[next];
                long j0, j1;
                rows_of(a, b, rows, &j0, &j1);
                for (long j = j0; j <= j1; j++) {
                    if (pass == 0)
                        at[j + 1]++;
                    else
                        x[at[j]++] = a[0] + ((double)j - a[1]) / (b[1] - a[1]) * (b[0] - a[0]);
                }
            }
        if (pass == 0)
            for (int j = 0; j < rows; j++)
                at[j + 1] += at[j];
        else /* at[j] now ends row j: shift back to starts */
            memmove(at + 1, at, sizeof *at * (size_t)rows), at[0] = 0;
    }
    size_t set = 0;
    for (int j = 0; j < rows; j++) {
        double *r = x + at[j];
        long n = at[j + 1] - at[j];
        qsort(r, (size_t)n, sizeof *r, cmp_double);
        for (long m = 0; m + 1 < n; m += 2) { /* centres x0 <= i < x1 are inside */
            if (!(r[m] < cols) || !(r[m + 1] > 0)) /* off the grid (or NaN) */
                continue;
            double lo = ceil(r[m]), hi = ceil(r[m + 1]) - 1;
            long i0 = lo < 0 ? 0 : (long)lo, i1 = hi > cols - 1 ? cols - 1 : (long)hi;
            for (long i = i0; i <= i1; i++)
                mask[(size_t)j * (size_t)cols + (size_t)i] = 1;
            set += i1 >= i0 ? (size_t)(i1 - i0 + 1) : 0;
        }
    }
    free(at);
    free(x);
    if (n_set)
        *n_set = set;
    return 0;
}
