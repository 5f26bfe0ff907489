/* model_internal.h - what the files of the contour surface share (model.c, model_grid.c,
 * model_fold.c, model_curve.c): a contour's curve, its polynomial pieces and their knots, a slice
 * pair's nets, a chain's fitted curves, and the functions one file calls in another. Private to
 * those files; the rest of surfd sees model.h. Calls go one way: model.c -> grid -> fold -> curve. */
#ifndef SURFD_MODEL_INTERNAL_H
#define SURFD_MODEL_INTERNAL_H

#include <stdbool.h>
#include <stddef.h>

#include "model.h"

struct curve {
    bool lsq;        /* linear-parabolic: least-squares lines instead of parabolas */
    int n;
    double (*p)[2];  /* points, rotated so that u increases from index 0 */
    double *u;       /* parameters in [0, 1), increasing */
    /* parabolic: at each point, whether it is a corner (C0 there) and the u-derivatives arriving at
     * it and leaving it (curve_shape; equal but at corners) */
    bool *corner;
    double (*t_in)[2], (*t_out)[2];
};

/* Power-basis cubic per segment i of a curve, in t = (u - u_i) / (u_{i+1} - u_i). */
struct curve_poly {
    int n;
    const double *u;     /* borrowed from the curve, or own_u; u_n = u_0 + 1 */
    double (*cx)[4], (*cy)[4];
    double *own_u;       /* its own knots, when redrawn (curve_refit) */
    int n_corner;
    double *corner;      /* the u of its corners (C0 there), increasing: each one a breakpoint */
};

/* fewer knots (model_curve.c) */
#define FIT_START 16       /* pieces to begin with */
#define FIT_MAX_KNOTS(n) (2 * (size_t)(n) + FIT_START) /* (the heart's curves take 1.1 to 1.5 n) */
#define WARP_MAX_KNOTS(n) (2 * FIT_MAX_KNOTS(n)) /* a warped curve's (curves_unfold) */

/* A knot of the redrawn curve: the curve's value and u-derivative there (the turn's end, u = 1,
 * read at its start). */
struct knot {
    double u, x, y, xu, yu;
};

/* A warp of a curve's parameter (curves_unfold): u -> φ(u) over a window [w0, w0 + len] of the turn
 * (mod 1), the identity elsewhere; φ is the monotone cubic Hermite through n nodes at even steps s of
 * the window, y and d its value and slope there (in the window's own [0, 1]; d = 1 at both ends, so
 * it joins the identity C1). */
struct warp {
    double w0, len;
    int n;
    double *y, *d;
};

/* A curve to redraw: c read at Φ(u) = w[0](w[1](... w[n_w - 1](u))), or as it is (n_w 0). */
struct redraw_src {
    const struct curve_poly *c;
    const struct warp *w;
    int n_w;
};

/* A slice pair's side surface as Bézier nets in (x, y), z being linear in v: one for each piece
 * between the merged breakpoints of the (up to) four curves the pair reads, in increasing u. */
struct pair_nets {
    size_t n, cap_u, cap_net, cap_brk;
    double *brk;            /* the merged breakpoints (scratch) */
    double (*u)[2];         /* each piece's [ua, ub] */
    double (*net)[4][4][2]; /* its points [a along u][b along z] */
};

/* A chain's curves (curves_build) as the methods read them: redrawn on their knots, and unfolded
 * if asked, with the pairs to be drawn ruled (ruled[k]: pair k, k+1; NULL when not unfolded). */
struct fitted {
    int n;
    struct curve *cv;
    struct curve_poly *cp;
    bool *ruled;
};

/* ---- one file's functions that another calls (their comments at their definitions) ---- */

/* model_grid.c */
int grid_count(const struct contour_set *cs);
int coons_surface(const struct contour_set *cs, bool polar, const struct sf_progress *pr, struct patch_set *set);
int bspline_surface(const struct contour_set *cs, bool polar, const struct sf_progress *pr, struct patch_set *set);

/* model_fold.c */
void fitted_free(struct fitted *f);
int curves_fit(const struct contour_set *cs, bool lsq, bool polar, bool unfold, struct fitted *f);

/* model_curve.c */
void curve_free(struct curve *c);
int curve_build(const struct contour_slice *s, bool lsq, bool polar, struct curve *c);
int curves_build(const struct contour_set *cs, bool lsq, bool polar, struct curve *cv);
int curve_poly_build(const struct curve *c, struct curve_poly *cp);
void curve_poly_free(struct curve_poly *cp);
void curve_poly_at(const struct curve_poly *cp, int i, double u, double *x, double *y, double *xu, double *yu);
int curve_poly_segment(const struct curve_poly *cp, double u);
struct knot knot_at(const struct curve_poly *c, double u);
double curve_tol(const struct curve_poly *c);
int curve_redraw(const struct redraw_src *src, double tol, size_t cap, struct curve_poly *out);
int curve_refit(struct curve_poly *c);
int cmp_double(const void *a, const void *b);
void pair_reads(int n, int k, bool ruled, int *first, int *last);
void slice_weights(const struct contour_set *cs, bool lsq, bool ruled, int k, double z, double w[4], int *j0,
                   int *m);
void pair_nets_free(struct pair_nets *pn);
int pair_nets(const struct contour_set *cs, bool lsq, bool ruled, const struct curve_poly *cp, int k,
              struct pair_nets *pn);

#endif
