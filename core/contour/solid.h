/* solid.h - a contour model as a closed solid: one tube per chain of contours (model.h), each a
 * stack of bands of Bézier patches that closes on itself, every patch oriented outward (holes'
 * tubes face into the hole). The same patches are rendered, meshed, exported and integrated.
 *
 * A tube from bottom to top: [cap] [wall | dome] side bands... [wall | dome] [cap].
 * - side: the method's surface, one band per pair of neighbouring levels;
 * - wall: the end curve extruded flat by the chain's extension (slab caps, branchings, islands,
 *   and a dome that did not close), bicubic with z linear in v;
 * - dome (ours; the seeds are silent): the end curve scaled about its centroid by ρ(s), with
 *   ρ² = q(s)/q(0) the quadratic through the last three section areas (exact for quadric ends),
 *   so every section's area is q(s) and the solid's volume that of model_volume_closed. The
 *   profile (s, ρ) is a conic, an exact rational quadratic, so the dome patches are rational of
 *   degree (3, 2) and end in the apex;
 * - cap: a flat end, as patches that fan from the end curve to its centroid (the area they
 *   enclose is exact; on a shape that is not star-shaped about its centroid they fold, which
 *   meshes avoid by triangulating the end polygon instead).
 * Within a band, patches run in increasing u over [0, 1] (domain u0..u1), t = local v runs up. */
#ifndef SURFD_SOLID_H
#define SURFD_SOLID_H

#include "model.h"

enum band_kind { BAND_SIDE, BAND_WALL, BAND_DOME, BAND_CAP };

struct band {
    enum band_kind kind;
    size_t first, n;     /* patches set.patches[first .. first+n) */
    double area;         /* a cap's area (its fan may fold; the area its rim encloses does not) */
};

struct tube {
    bool hole;
    int first, n;        /* bands */
    double volume_ends;  /* the dome and wall volumes beyond the side surface (signed as the tube) */
    struct model_closed side; /* with model_opts.closed: the side's volume with flat ends, closed form
                               * (model_side_closed; unsigned), 0 for an island's prism (in
                               * volume_ends), NAN for the grid methods; and the time it took */
};

struct solid {
    struct patch_set set;    /* cw resolved (nurbs_patches_fix done) */
    struct band *bands;
    int n_bands;
    size_t cap_bands;
    struct tube *tubes;
    int n_tubes;
    int dome_fallbacks;      /* stack ends where the dome did not close: a wall of half a spacing */
    struct model_chain *chains; /* the tubes' chains, in the same order */
    const struct sf_progress *progress; /* the build's (model_opts), polled by solid_mesh too; borrowed */
};

/* Builds the solid of cleaned contours by the method and parameterisation, with the caps. Returns 0 or an SF_* code with
 * err. */
int solid_build(const struct contour_set *cs, struct model_opts o, enum model_caps caps, struct solid *s,
                struct sf_err *err);
void solid_free(struct solid *s);

/* The point of band `band` at u in [0, 1) along the tube and t in [0, 1] up the band. */
vec3 solid_point(const struct solid *s, int band, double u, double t);

struct solid_measures {
    double volume;      /* divergence theorem over every patch (seed 000 eq. 21–22), signed by orientation */
    double volume_grid; /* the same by the 10 x 10 grid rule per patch (eq. 23, nodes i/10) */
    double area;
    double lo[3], hi[3];
};
void solid_measure(const struct solid *s, struct solid_measures *m);

/* A triangle mesh of the solid, within tol (length units) of the surface: closed (every edge in
 * exactly two triangles, opposite ways) per tube, triangles counter-clockwise seen from outside.
 * Returns 0, SF_ENOMEM, SF_ELIMIT past SOLID_MESH_MAX_TRIANGLES (a tolerance too fine for the model), or
 * SF_ECANCEL when the solid's progress asks it to stop. */
#define SOLID_MESH_MAX_TRIANGLES (4u << 20) /* 200 MB of binary STL */
struct solid_mesh {
    double (*v)[3];
    size_t n_v, cap_v;
    unsigned (*t)[3];
    size_t n_t, cap_t;
};
int solid_mesh(const struct solid *s, double tol, struct solid_mesh *m);
/* 1e-4 of the bounds' diagonal: meshes within 0.1 % of the model's volume (tests/api/test_contour_model.c),
 * finer than most uses need (a lung's 93 MB of STL). */
double solid_default_tolerance(const struct solid_measures *m);
/* The mesh at the default tolerance, tied to the model: the coarsest tried (from 1e-2 of volume /
 * area down, never below solid_default_tolerance) whose volume is within 0.05 % of the model's;
 * *tol receives it. Returns as solid_mesh. */
int solid_mesh_default(const struct solid *s, const struct solid_measures *sm, struct solid_mesh *m, double *tol);
/* The flat surface of the planes where tubes end and begin (issue 18: a model's patches close as one
 * solid where its contours branch), and of the ends whose fans fold (not star-shaped about their
 * centroids): the caps' rims sampled within tol and joined as solid_mesh joins them (join.h), as
 * regions, one a plane and side: the boundary of the joined triangles facing
 * that way, as closed loops in (x, y) whose even-odd inside is the region (loop k: counts[k] points
 * from pt + the earlier counts, the first not repeated). skip (caller's array of n_bands) is set for
 * the cap bands the regions replace. Returns 0 or SF_ENOMEM. */
struct cap_region {
    double z;
    bool up;
    int n_loops;
    size_t *counts;
    double (*pt)[2];
    double lo[2], hi[2];     /* the loops' bounds */
};
struct cap_regions {
    struct cap_region *r;
    int n;
};
int solid_join_caps(const struct solid *s, double tol, struct cap_regions *out, bool *skip);
void solid_cap_regions_free(struct cap_regions *r);
void solid_mesh_free(struct solid_mesh *m);
/* Signed volume enclosed (sum of signed tetrahedra from the origin). */
double solid_mesh_volume(const struct solid_mesh *m);

#endif
