/* model_grid.c - the grid methods: Coons and B-spline patches through each contour's curve sampled
 * at N even steps of u (model_side_closed chooses them). */
#include "model_internal.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "../base/mem.h"

/* ---- grid methods: Coons and B-spline ------------------------------------------------------------
 * Both need the same point count on every slice (METHODS.md §2): each contour's curve is sampled at
 * N even steps of u, N the most points any contour has (at least 8). The curves' parameter starts
 * where the +x ray out of the centroid crosses them, so column k lines up from slice to slice. */

#define GRID_MIN 8

int grid_count(const struct contour_set *cs)
{
    int N = GRID_MIN;
    for (int j = 0; j < cs->n_slices; j++)
        N = cs->s[j].n > N ? cs->s[j].n : N;
    return N;
}

/* Q[j*N + k] = (x, y, z) of slice j at u = k/N. NULL when out of memory. */
static double (*grid_sample(const struct contour_set *cs, int N, bool polar))[3]
{
    int n = cs->n_slices;
    double(*Q)[3] = malloc(sizeof *Q * (size_t)n * (size_t)N);
    struct fitted f;
    if (curves_fit(cs, false, polar, false, &f) || !Q) {
        free(Q);
        Q = NULL;
    }
    for (int j = 0; Q && j < n; j++)
        for (int k = 0; k < N; k++) {
            double *q = Q[(size_t)j * N + k], u = (double)k / N, xu, yu;
            curve_poly_at(&f.cp[j], curve_poly_segment(&f.cp[j], u), u, &q[0], &q[1], &xu, &yu);
            q[2] = cs->s[j].z;
        }
    fitted_free(&f);
    return Q;
}

/* Appends a bicubic with cw still a pool offset (as nurbs_extract does); NULL when out of memory. */
static double (*append_bicubic(struct patch_set *set, double u0, double u1, double v0, double v1))[4]
{
    if (mem_reserve((void **)&set->patches, &set->cap, set->n + 1, sizeof *set->patches) ||
        mem_reserve((void **)&set->pool, &set->cap_pool, set->n_pool + 16, sizeof *set->pool))
        return NULL;
    set->patches[set->n++] = (struct patch){.p = 3, .q = 3, .cw = (double(*)[4])(uintptr_t)set->n_pool, .u0 = u0, .u1 = u1, .v0 = v0, .v1 = v1};
    set->n_pool += 16;
    return set->pool + set->n_pool - 16;
}

/* Local interpolation by bicubic Coons patches (seeds 000/001 eq. 14–17, as METHODS.md corrects
 * them): per grid cell, corners, central-difference tangents (one-sided at the first and last slice:
 * ours, the seeds are silent), each in its own slot (the difference along the slices where the
 * matrix wants the derivative across them), and zero twist; P_B = H G Hᵀ puts the edge points at the
 * corners ± tangent/3 and the inner points at the corners ± both tangents/3. */
int coons_surface(const struct contour_set *cs, bool polar, const struct sf_progress *pr, struct patch_set *set)
{
    int n = cs->n_slices, N = grid_count(cs);
    double(*Q)[3] = grid_sample(cs, N, polar);
    if (!Q)
        return SF_ENOMEM;
#define AT(j, k) Q[(size_t)(j) * N + (size_t)(((k) % N + N) % N)]
    for (int j = 0; j + 1 < n; j++) {
        if (sf_poll(pr, (double)j / n, NULL)) {
            free(Q);
            return SF_ECANCEL;
        }
        for (int k = 0; k < N; k++) {
            double(*cw)[4] = append_bicubic(set, (double)k / N, (double)(k + 1) / N, cs->s[j].z, cs->s[j + 1].z);
            if (!cw) {
                free(Q);
                return SF_ENOMEM;
            }
            for (int a = 0; a < 2; a++)     /* corner along u: k + a */
                for (int b = 0; b < 2; b++) { /* ... across slices: j + b */
                    int jj = j + b, kk = k + a, jm = jj > 0 ? jj - 1 : jj, jp = jj + 1 < n ? jj + 1 : jj;
                    double su = a ? -1.0 / 3 : 1.0 / 3, sv = b ? -1.0 / 3 : 1.0 / 3;
                    for (int c = 0; c < 3; c++) {
                        double P = AT(jj, kk)[c];
                        double Tu = 0.5 * (AT(jj, kk + 1)[c] - AT(jj, kk - 1)[c]);
                        double Tv = (AT(jp, kk)[c] - AT(jm, kk)[c]) / (jp - jm);
                        int i0 = a ? 3 : 0, j0 = b ? 3 : 0, i1 = a ? 2 : 1, j1 = b ? 2 : 1;
                        cw[i0 * 4 + j0][c] = P;
                        cw[i1 * 4 + j0][c] = P + su * Tu;
                        cw[i0 * 4 + j1][c] = P + sv * Tv;
                        cw[i1 * 4 + j1][c] = P + su * Tu + sv * Tv; /* zero twist */
                    }
                }
            for (int q = 0; q < 16; q++)
                cw[q][3] = 1.0;
        }
    }
#undef AT
    free(Q);
    return 0;
}

/* Solves the periodic system (x[k-1] + 4 x[k] + x[k+1]) / 6 = d[k], k = 0..N-1 (N >= 3), in place
 * on d (three columns): the cyclic tridiagonal system of uniform periodic cubic interpolation, by
 * the Thomas algorithm with a Sherman–Morrison correction for the two corner entries. */
static int solve_periodic(double (*d)[3], int N)
{
    double *c = malloc(sizeof *c * (size_t)N), (*y)[3] = malloc(sizeof *y * (size_t)N),
           *z = malloc(sizeof *z * (size_t)N);
    if (!c || !y || !z) {
        free(c), free(y), free(z);
        return SF_ENOMEM;
    }
    /* A = T + u vᵀ with u = (γ, 0, .., 0, 1/6), v = (1, 0, .., 0, (1/6)/γ), T tridiagonal */
    const double a = 1.0 / 6, b = 4.0 / 6, gamma = -b;
    double rhs_u[2] = {gamma, a};
    for (int pass = 0; pass < 2; pass++) { /* pass 0: T y = d (three columns); pass 1: T z = u */
        double prev_c = 0.0;
        for (int k = 0; k < N; k++) {
            double diag = b - (k == 0 ? gamma : 0.0) - (k == N - 1 ? a * a / gamma : 0.0);
            double m = k == 0 ? diag : diag - a * prev_c;
            c[k] = a / m;
            prev_c = c[k];
            if (pass == 0)
                for (int q = 0; q < 3; q++)
                    y[k][q] = ((k ? -a * y[k - 1][q] : 0.0) + d[k][q]) / m;
            else
                z[k] = ((k ? -a * z[k - 1] : 0.0) + (k == 0 ? rhs_u[0] : k == N - 1 ? rhs_u[1] : 0.0)) / m;
        }
        for (int k = N - 2; k >= 0; k--) {
            if (pass == 0)
                for (int q = 0; q < 3; q++)
                    y[k][q] -= c[k] * y[k + 1][q];
            else
                z[k] -= c[k] * z[k + 1];
        }
    }
    double vz = z[0] + a / gamma * z[N - 1];
    for (int q = 0; q < 3; q++) {
        double vy = y[0][q] + a / gamma * y[N - 1][q], f = vy / (1.0 + vz);
        for (int k = 0; k < N; k++)
            d[k][q] = y[k][q] - f * z[k];
    }
    free(c), free(y), free(z);
    return 0;
}

/* Solves A X = B in place on B (m right-hand sides of 3), A n x n dense, Gaussian elimination with
 * partial pivoting. A is destroyed. */
static void solve_dense(double *A, int n, double (*B)[3], int m)
{
    for (int c = 0; c < n; c++) {
        int piv = c;
        for (int r = c + 1; r < n; r++)
            if (fabs(A[(size_t)r * n + c]) > fabs(A[(size_t)piv * n + c]))
                piv = r;
        if (piv != c) {
            for (int k = 0; k < n; k++) {
                double t = A[(size_t)c * n + k];
                A[(size_t)c * n + k] = A[(size_t)piv * n + k], A[(size_t)piv * n + k] = t;
            }
            for (int k = 0; k < m; k++)
                for (int q = 0; q < 3; q++) {
                    double t = B[(size_t)c * m + k][q];
                    B[(size_t)c * m + k][q] = B[(size_t)piv * m + k][q], B[(size_t)piv * m + k][q] = t;
                }
        }
        for (int r = c + 1; r < n; r++) {
            double f = A[(size_t)r * n + c] / A[(size_t)c * n + c];
            if (f == 0.0)
                continue;
            for (int k = c; k < n; k++)
                A[(size_t)r * n + k] -= f * A[(size_t)c * n + k];
            for (int k = 0; k < m; k++)
                for (int q = 0; q < 3; q++)
                    B[(size_t)r * m + k][q] -= f * B[(size_t)c * m + k][q];
        }
    }
    for (int c = n - 1; c >= 0; c--)
        for (int k = 0; k < m; k++)
            for (int q = 0; q < 3; q++) {
                double sum = B[(size_t)c * m + k][q];
                for (int r = c + 1; r < n; r++)
                    sum -= A[(size_t)c * n + r] * B[(size_t)r * m + k][q];
                B[(size_t)c * m + k][q] = sum / A[(size_t)c * n + c];
            }
}

static int cmp_span(const void *a, const void *b)
{
    const struct patch *x = a, *y = b;
    return x->v0 != y->v0 ? (x->v0 > y->v0) - (x->v0 < y->v0) : (x->u0 > y->u0) - (x->u0 < y->u0);
}

/* Global interpolation by one B-spline surface (seed 000 eq. 28–31): cubic and periodic along the
 * contours (uniform knots, the first three control columns wrapped, eq. 29), cubic (or of degree
 * slices - 1) across them, clamped, at uniform parameters with averaged knots (Piegl & Tiller 9.8).
 * The two directions are solved one after the other, each with a proper solver: the cyclic
 * tridiagonal system along u, Gaussian elimination with pivoting across (the thesis used
 * Gauss–Jordan on the whole). Bézier extraction gives the patches. */
int bspline_surface(const struct contour_set *cs, bool polar, const struct sf_progress *pr, struct patch_set *set)
{
    int n = cs->n_slices, N = grid_count(cs), q = n > 3 ? 3 : n - 1, rc = SF_ENOMEM;
    double(*Q)[3] = grid_sample(cs, N, polar), *A = malloc(sizeof *A * (size_t)n * n);
    struct surface s = {0};
    if (!Q || !A || nurbs_surface_alloc(&s, SURF_BSPLINE, 3, q, N + 3, n, NULL))
        goto out;
    for (int j = 0; j < n; j++) /* along u, slice by slice */
        if ((rc = sf_poll(pr, 0.3 * j / n, NULL)) || (rc = solve_periodic(Q + (size_t)j * N, N)))
            goto out;
    rc = SF_ENOMEM;
    for (int k = 0; k < n + q + 1; k++) { /* across: clamped, averaged knots */
        if (k <= q)
            s.knots_v[k] = 0.0;
        else if (k >= n)
            s.knots_v[k] = 1.0;
        else {
            double sum = 0.0;
            for (int i = k - q; i < k; i++)
                sum += (double)i / (n - 1);
            s.knots_v[k] = sum / q;
        }
    }
    memset(A, 0, sizeof *A * (size_t)n * n);
    for (int i = 0; i < n; i++) {
        double Nb[PATCH_MAX_DEGREE + 1];
        int r = nurbs_basis(s.knots_v, n, q, (double)i / (n - 1), Nb);
        for (int b = 0; b <= q; b++)
            A[(size_t)i * n + (size_t)(r - q + b)] = Nb[b];
    }
    solve_dense(A, n, Q, N); /* rows: slices; right-hand sides: the N columns */
    if ((rc = sf_poll(pr, 0.6, NULL)))
        goto out;
    rc = SF_ENOMEM;
    for (int k = 0; k < N + 3 + 4; k++)
        s.knots_u[k] = (double)(k - 3) / N;
    /* control column i along u, j across; the curve at u = k/N is (x[k-1] + 4 x[k] + x[k+1]) / 6 of
     * columns k..k+2, so column i holds x[i-1] and the first three are wrapped round (eq. 29) */
    for (int i = 0; i < N + 3; i++)
        for (int j = 0; j < n; j++)
            memcpy(&s.points[3 * ((size_t)i * n + j)], Q[(size_t)j * N + (size_t)((i + N - 1) % N)], sizeof(double) * 3);
    size_t first = set->n;
    if (!(rc = nurbs_extract(&s, 0, set))) /* span by span across, each in increasing u */
        qsort(set->patches + first, set->n - first, sizeof *set->patches, cmp_span);
out:
    nurbs_surface_free(&s);
    free(Q);
    free(A);
    return rc;
}

