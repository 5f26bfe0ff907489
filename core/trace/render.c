/* render.c - frames: camera and lights from the scene, the methods of render.method, and
 * Blinn–Phong shading with shadow rays. What each method does for a primary ray:
 *   map        preliminary-value map seed, refined by the seed's method for the object's kind
 *              (gradient descent for Bézier eq. 4, steepest descent for B-spline eq. 9,
 *              Newton–Cramer for NURBS eq. 10–13); where it fails, the exact hierarchy
 *   auto       the map seed refined by Newton–Cramer for every kind (the fastest exact way)
 *   bvh        the exact hierarchy alone
 *   mesh       triangles (the speed reference; not exact)
 *   montecarlo eq. 3 random seeds in every patch whose box the ray meets, then eq. 4
 * Shadow rays always go through the exact hierarchy (the mesh for the mesh method). */
#include "render.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../base/clock.h"
#include "camera.h"
#include "map.h"
#include "solve.h"
#include "srgb.h"

#define AMBIENT 0.12          /* ambient fraction of the albedo */
#define MC_SAMPLES 64         /* eq. 3 sample count N */
#define SHADOW_EPS 1e-7       /* shadow ray start offset, relative to the scene's size */
#define MESH_SHADOW_EPS 1e-4  /* the same from a triangle of a mesh: float triangles, and shading
                               * normals that are not the facet's, need more room (0.03 mm on a head) */
#define SHEET_PX 2.0          /* pixels of depth between a seed's fragment and a root on its own sheet */
#define LEAF_FINE_PX 0.5      /* pixels (of the scene's size over the picture's larger side) a flat leaf
                               * may still deviate by before it splits on (bvh_build_scene's fine) */
#define SHADE_CHUNK 64        /* pixels of a row shaded together: their shadow rays go out at once */

struct frame {
    const struct scene *sc;
    bool borrowed;            /* ps, exact, mesh and meshes are another frame's (frame_prepare_from) */
    struct camera cam;
    struct patch_set ps;
    vec3 lo, hi;
    double diag;              /* scene size: the unit of every relative tolerance */
    double tol2;              /* squared root residual, world units */
    struct light *lights;     /* resolved (defaults filled in) */
    struct dray *toward;      /* per light: a directional light's shadow rays' direction and planes */
    int n_lights;
    struct bvh *exact, *mesh;
    const struct trimesh **meshes; /* the scene's triangle meshes, for the hierarchy */
    struct map *map;
    double t0, prepare_ms;  /* when its preparation began; how long it took, to frame_end */
    float *rgba, *depth, *normal, *uv, *id;
    unsigned char *srgb8;     /* srgb8_only: the picture, in place of rgba and depth */
    unsigned char bg8[3 * SHADE_CHUNK]; /* a run of background pixels in it (each band starts its rows so) */
    struct srgb_table *srgb;
};

void render_stats_add(struct render_stats *into, const struct render_stats *s)
{
    into->rays += s->rays;
    into->primary += s->primary;
    into->hits += s->hits;
    into->refinements += s->refinements;
    into->iterations += s->iterations;
    into->misses += s->misses;
    into->fallback_hits += s->fallback_hits;
    into->shadow += s->shadow;
    into->shadow_iterations += s->shadow_iterations;
}

void frame_free(struct frame *fr)
{
    if (!fr)
        return;
    map_free(fr->map);
    if (!fr->borrowed) {
        bvh_free(fr->exact);
        bvh_free(fr->mesh);
        free(fr->meshes);
        nurbs_patch_set_free(&fr->ps);
    }
    free(fr->lights);
    free(fr->toward);
    free(fr->rgba);
    free(fr->depth);
    free(fr->normal);
    free(fr->uv);
    free(fr->id);
    free(fr->srgb8);
    free(fr->srgb);
    free(fr);
}

/* The orthographic half extents that hold the eight corners of the bounds with a 5 % margin, for
 * the camera's axes (the view's height; its width from the aspect unless the scene gives one). */
static void fit_ortho(struct frame *fr)
{
    const struct scene *sc = fr->sc;
    double hh = 0.0;
    for (int k = 0; k < 8; k++) {
        vec3 p = v3(k & 1 ? fr->hi.x : fr->lo.x, k & 2 ? fr->hi.y : fr->lo.y, k & 4 ? fr->hi.z : fr->lo.z);
        vec3 d = v3_sub(p, fr->cam.eye);
        hh = fmax(hh, fmax(fabs(v3_dot(d, fr->cam.u)), fabs(v3_dot(d, fr->cam.r)) / fr->cam.aspect) / 0.95);
    }
    camera_make_ortho(&fr->cam, sc->view_height > 0.0 ? sc->view_height : fmax(2.0 * hh, 1e-9 * fr->diag),
                      sc->view_width);
}

static void place_camera(struct frame *fr)
{
    const struct scene *sc = fr->sc;
    if (sc->has_camera) {
        camera_init(&fr->cam, sc->eye, sc->target, sc->up, sc->fov_deg, sc->width, sc->height);
        if (sc->ortho)
            fit_ortho(fr);
        return;
    }
    /* look from azimuth/elevation (azimuth from -y towards +x, z up), or along an axis, at the
     * bounds' centre */
    vec3 c = v3_scale(v3_add(fr->lo, fr->hi), 0.5), dir, up = v3(0, 0, 1);
    if (sc->view) {
        scene_view_axes(sc->view, &dir, &up);
    } else {
        double az = sc->azimuth_deg * M_PI / 180, el = sc->elevation_deg * M_PI / 180;
        dir = v3(sin(az) * cos(el), -cos(az) * cos(el), sin(el));
    }
    if (sc->ortho) { /* from outside the bounds' sphere: every object in front of the eye's plane */
        camera_init(&fr->cam, v3_mad(c, dir, fr->diag), c, up, sc->fov_deg, sc->width, sc->height);
        fit_ortho(fr);
        return;
    }
    /* from the nearest distance at which all eight corners of the bounds fit the view with a 5 %
     * margin */
    struct camera probe;
    camera_init(&probe, v3_add(c, dir), c, up, sc->fov_deg, sc->width, sc->height);
    double tv = 0.95 * probe.th, th = tv * probe.aspect, dist = 0.0;
    for (int k = 0; k < 8; k++) {
        vec3 p = v3(k & 1 ? fr->hi.x : fr->lo.x, k & 2 ? fr->hi.y : fr->lo.y, k & 4 ? fr->hi.z : fr->lo.z);
        vec3 d = v3_sub(p, c);
        double x = v3_dot(d, probe.r), y = v3_dot(d, probe.u), z = v3_dot(d, probe.f);
        /* the corner is at depth dist + z from the eye: it needs |x| <= th (dist + z), |y| likewise */
        dist = fmax(dist, fmax(fabs(x) / th - z, fabs(y) / tv - z));
    }
    dist = fmax(dist, 1e-6 * fr->diag);
    camera_init(&fr->cam, v3_mad(c, dir, dist), c, up, sc->fov_deg, sc->width, sc->height);
}

static int resolve_lights(struct frame *fr)
{
    const struct scene *sc = fr->sc;
    int n = sc->n_lights ? sc->n_lights : 2;
    fr->lights = malloc(sizeof *fr->lights * (size_t)n);
    fr->toward = calloc((size_t)n, sizeof *fr->toward);
    if (!fr->lights || !fr->toward)
        return SF_ENOMEM;
    fr->n_lights = n;
    if (sc->n_lights) {
        memcpy(fr->lights, sc->lights, sizeof *fr->lights * (size_t)n);
    } else { /* key light from the upper left behind the viewer, and a weak head light */
        const struct camera *c = &fr->cam;
        vec3 from = v3_norm(v3_add(v3_add(v3_scale(c->r, -0.6), v3_scale(c->u, 0.9)), v3_scale(c->f, -0.7)));
        fr->lights[0] = (struct light){false, v3_scale(from, -1.0), v3(0.85, 0.85, 0.85), false};
        fr->lights[1] = (struct light){false, c->f, v3(0.25, 0.25, 0.25), true};
    }
    for (int k = 0; k < n; k++) /* every shadow ray toward a directional light shares these */
        if (!fr->lights[k].point)
            solve_ray_init(&fr->toward[k], v3(0, 0, 0), v3_scale(fr->lights[k].v, -1.0));
    return 0;
}

/* The framed eye's coordinates at most: a ray's float origin past ~1.8e18 aborts Embree. */
#define FRAME_MAX_EYE 1e17
#define AUTO_MAP_PIXELS_PER_PATCH 64 /* frame pixels per patch below which auto leaves the map out */

/* The view's part of a frame whose hierarchy is in place: camera, lights, buffers, the map begun
 * (whole: finished too). Frees fr on failure. */
static int frame_view(struct frame *fr, bool whole, struct frame **out, struct sf_err *err)
{
    const struct scene *sc = fr->sc;
    int rc = 0;
    place_camera(fr);
    if (!(fabs(fr->cam.eye.x) <= FRAME_MAX_EYE && fabs(fr->cam.eye.y) <= FRAME_MAX_EYE &&
          fabs(fr->cam.eye.z) <= FRAME_MAX_EYE)) {
        frame_free(fr);
        return sf_fail(err, SF_EINVAL, "/camera/fov_deg",
                       "framing the objects at fov_deg %g puts the eye beyond ±%g; widen the view", sc->fov_deg,
                       FRAME_MAX_EYE);
    }
    if (resolve_lights(fr))
        goto out_fail_mem;

    size_t np = (size_t)sc->width * sc->height;
    if (sc->srgb8_only) {
        if (!(fr->srgb8 = malloc(3 * np)) || !(fr->srgb = malloc(sizeof *fr->srgb)))
            goto out_fail_mem;
        srgb_table_init(fr->srgb);
        const float bg[3] = {(float)sc->background.x, (float)sc->background.y, (float)sc->background.z};
        for (int k = 0; k < 3 * SHADE_CHUNK; k++)
            fr->bg8[k] = srgb8(fr->srgb, bg[k % 3]);
    } else {
        fr->rgba = malloc(sizeof(float) * 4 * np);
        fr->depth = malloc(sizeof(float) * np);
        if (!fr->rgba || !fr->depth)
            goto out_fail_mem;
        if ((sc->aovs & AOV_NORMAL) && !(fr->normal = malloc(sizeof(float) * 3 * np)))
            goto out_fail_mem;
        if ((sc->aovs & AOV_UV) && !(fr->uv = malloc(sizeof(float) * 2 * np)))
            goto out_fail_mem;
        if ((sc->aovs & AOV_ID) && !(fr->id = malloc(sizeof(float) * np)))
            goto out_fail_mem;
    }
    /* auto traces primaries through the map where patches are large on screen; with many small ones
     * (a contour model's thousands) most pixels hold more candidates than the map keeps, and the
     * hierarchy alone is the faster (the heart's 19 014 patches at 500x400: 274 against 368 ms) */
    bool map_wanted = !sc->n_meshes && !sc->ortho && /* the map knows patches in perspective alone */
                      (sc->method == METHOD_MAP ||
                       (sc->method == METHOD_AUTO && fr->ps.n * AUTO_MAP_PIXELS_PER_PATCH <= np));
    if (map_wanted)
        rc = map_begin(fr->ps.patches, fr->ps.n, fr->exact, &fr->cam, &fr->map, err);
    if (!rc && whole)
        rc = frame_finish(fr, err);
    if (rc) {
        frame_free(fr);
        return rc;
    }
    *out = fr;
    return 0;

out_fail_mem:
    frame_free(fr);
    return sf_fail(err, SF_ENOMEM, "", "out of memory preparing the frame");
}

int frame_steps(const struct frame *fr) { return fr->map && map_parts(fr->map) ? MAP_STEPS : 0; }

int frame_parts(const struct frame *fr) { return fr->map ? map_parts(fr->map) : 0; }

void frame_part(struct frame *fr, int step, int p) { map_part(fr->map, step, p); }

int frame_end(struct frame *fr, struct sf_err *err)
{
    int rc = fr->map ? map_end(fr->map, err) : 0;
    fr->prepare_ms = sf_now_ms() - fr->t0;
    return rc;
}

int frame_finish(struct frame *fr, struct sf_err *err)
{
    for (int step = 0; step < frame_steps(fr); step++)
        for (int p = 0; p < frame_parts(fr); p++)
            frame_part(fr, step, p);
    return frame_end(fr, err);
}

static int prepare(const struct scene *sc, struct bvh_device *dev, bool whole, struct frame **out, struct sf_err *err)
{
    double t0 = sf_now_ms();
    *out = NULL;
    int rc = scene_validate(sc, err);
    if (rc)
        return rc;
    struct frame *fr = calloc(1, sizeof *fr);
    if (!fr)
        return sf_fail(err, SF_ENOMEM, "", "out of memory");
    fr->sc = sc;
    fr->t0 = t0;
    if ((rc = scene_patches(sc, &fr->ps, err))) {
        free(fr);
        return rc;
    }

    fr->lo = v3(INFINITY, INFINITY, INFINITY);
    fr->hi = v3(-INFINITY, -INFINITY, -INFINITY);
    for (size_t k = 0; k < fr->ps.n; k++) {
        vec3 a, b;
        bezier_bounds(&fr->ps.patches[k], &a, &b);
        fr->lo = v3_min(fr->lo, a);
        fr->hi = v3_max(fr->hi, b);
    }
    if (sc->n_meshes && !(fr->meshes = malloc(sizeof *fr->meshes * (size_t)sc->n_meshes))) {
        frame_free(fr);
        return sf_fail(err, SF_ENOMEM, "", "out of memory");
    }
    for (int k = 0; k < sc->n_meshes; k++) {
        const struct trimesh *m = &sc->meshes[k].m;
        fr->meshes[k] = m;
        for (size_t v = 0; v < m->n_vert; v++) {
            vec3 p = v3(m->pos[3 * v], m->pos[3 * v + 1], m->pos[3 * v + 2]);
            fr->lo = v3_min(fr->lo, p);
            fr->hi = v3_max(fr->hi, p);
        }
    }
    fr->diag = v3_len(v3_sub(fr->hi, fr->lo));
    if (!(fr->diag > 0.0) || !isfinite(fr->diag)) {
        frame_free(fr);
        return sf_fail(err, SF_EINVAL, "/objects", "the objects have no extent (every control point is the same)");
    }
    fr->tol2 = (sc->tolerance * fr->diag) * (sc->tolerance * fr->diag);
    if (sc->method == METHOD_MESH)
        rc = bvh_build_mesh(dev, fr->ps.patches, fr->ps.n, sc->mesh_tolerance * fr->diag, &fr->mesh, err);
    else
        rc = bvh_build_scene(dev, fr->ps.patches, fr->ps.n, fr->tol2,
                             LEAF_FINE_PX * fr->diag / (sc->width > sc->height ? sc->width : sc->height), fr->meshes,
                             sc->n_meshes, &fr->exact, err);
    if (rc) {
        frame_free(fr);
        return rc;
    }
    return frame_view(fr, whole, out, err);
}

int frame_prepare(const struct scene *sc, struct bvh_device *dev, struct frame **out, struct sf_err *err)
{
    return prepare(sc, dev, true, out, err);
}

int frame_begin(const struct scene *sc, struct bvh_device *dev, struct frame **out, struct sf_err *err)
{
    return prepare(sc, dev, false, out, err);
}

static int prepare_from(const struct scene *sc, const struct frame *base, bool whole, struct frame **out,
                        struct sf_err *err)
{
    double t0 = sf_now_ms();
    *out = NULL;
    int rc = scene_validate(sc, err);
    if (rc)
        return rc;
    if (sc->objects != base->sc->objects || sc->n_objects != base->sc->n_objects || sc->meshes != base->sc->meshes ||
        sc->n_meshes != base->sc->n_meshes || sc->tolerance != base->sc->tolerance ||
        (sc->method == METHOD_MESH) != (base->mesh != NULL) ||
        (base->mesh && sc->mesh_tolerance != base->sc->mesh_tolerance))
        return sf_fail(err, SF_EINVAL, "", "the frame's hierarchy was built for other objects or tolerances");
    struct frame *fr = calloc(1, sizeof *fr);
    if (!fr)
        return sf_fail(err, SF_ENOMEM, "", "out of memory");
    fr->sc = sc;
    fr->t0 = t0;
    fr->borrowed = true; /* the base's patches, bounds and hierarchies: read-only, shared */
    fr->ps = base->ps, fr->lo = base->lo, fr->hi = base->hi, fr->diag = base->diag, fr->tol2 = base->tol2;
    fr->exact = base->exact, fr->mesh = base->mesh, fr->meshes = base->meshes;
    return frame_view(fr, whole, out, err);
}

int frame_prepare_from(const struct scene *sc, const struct frame *base, struct frame **out, struct sf_err *err)
{
    return prepare_from(sc, base, true, out, err);
}

int frame_begin_from(const struct scene *sc, const struct frame *base, struct frame **out, struct sf_err *err)
{
    return prepare_from(sc, base, false, out, err);
}

size_t frame_hierarchy_bytes(const struct frame *fr)
{
    size_t n = bvh_bytes(fr->exact, fr->ps.n) + bvh_bytes(fr->mesh, fr->ps.n);
    for (size_t k = 0; k < fr->ps.n; k++) /* the patches and their control points */
        n += sizeof *fr->ps.patches + sizeof *fr->ps.patches[k].cw * (size_t)(fr->ps.patches[k].p + 1) *
                                          (size_t)(fr->ps.patches[k].q + 1);
    for (int k = 0; k < fr->sc->n_meshes; k++)
        n += fr->sc->meshes[k].m.n_tri * 64 + fr->sc->meshes[k].m.n_vert * 24;
    return n;
}

/* ---- primary rays ----------------------------------------------------------------------- */

/* The row's last hit and its step from the pixel before (zero after a change of patch): the
 * next pixel's seed on that patch, one pixel on, is off by about the square of that step. */
struct row_seed {
    int patch; /* -1: the last pixel missed */
    double u, v, du, dv;
};

/* Refines one map candidate with the method the frame asks for; auto seeds from the row's last
 * hit where it is on the same patch (rs may be NULL: the map's seed). *cut: a root was found that
 * is no hit (the trims cut it away, or it lies behind the eye). */
static bool refine(const struct frame *fr, const struct map_cand *c, const struct row_seed *rs, const struct dray *r,
                   struct solve_hit *h, bool *cut)
{
    const struct patch *pt = &fr->ps.patches[c->patch];
    const struct solve_box all = {0, 1, 0, 1};
    bool ok;
    if (fr->sc->method == METHOD_AUTO) {
        double u = c->u, v = c->v;
        if (rs && rs->patch == c->patch) {
            u = dmin(1.0, dmax(0.0, rs->u + rs->du));
            v = dmin(1.0, dmax(0.0, rs->v + rs->dv));
        }
        ok = solve_newton_seeded(pt, r, u, v, &all, fr->tol2, h);
    } else {
        switch (fr->sc->objects[pt->surface].surf.kind) {
        case SURF_BEZIER: ok = solve_gradient(pt, r, c->u, c->v, &all, fr->tol2, h); break;
        case SURF_BSPLINE: ok = solve_steepest(pt, r, c->u, c->v, &all, fr->tol2, h); break;
        default: ok = solve_newton_seeded(pt, r, c->u, c->v, &all, fr->tol2, h); break;
        }
    }
    bool hit = ok && h->t > 0.0 && bezier_kept(pt, h->u, h->v); /* a root the trims cut away is no hit */
    *cut = ok && !hit;
    return hit;
}

/* Branch and bound over the pixel's candidates (nearest depth bound first): a candidate whose
 * bound lies behind the best root so far cannot hold a nearer one. Where a candidate ahead of
 * the root stays unresolved (no root found, or one on a farther sheet), the exact hierarchy
 * searches it for a nearer root; where the list overflowed ahead of the root, it searches all. */
static bool primary_map(const struct frame *fr, const struct map_rows *rw, size_t at, const struct row_seed *rs,
                        const struct dray *r, struct bvh_hit *hit, struct render_stats *st)
{
    const struct map_cand *c = &rw->cand[at * MAP_CANDS];
    const int n = rw->n[at];
    const double zscale = v3_dot(r->d, fr->cam.f); /* camera depth per unit of t */
    bool found = false;
    int open[MAP_CANDS], n_open = 0;   /* the patches not resolved */
    float open_zlo[MAP_CANDS];
    bool open_ok[MAP_CANDS];           /* ... and whether a root of theirs was found */
    bool open_cut[MAP_CANDS];          /* ... or one that is no hit (refine) */
    /* a root this far (relative) behind its seed's fragment lies on a farther sheet of the patch */
    const double sheet = SHEET_PX * 2.0 * fr->cam.th / fr->cam.H;
    for (int k = 0; k < n; k++) {
        if (found && c[k].zlo > hit->t * zscale)
            break;
        const double far = c[k].zs * (1.0 + sheet); /* depth beyond which a root is on another sheet */
        struct solve_hit h;
        bool cut;
        st->refinements++;
        bool ok = refine(fr, &c[k], rs, r, &h, &cut);
        st->iterations += h.iters;
        if ((!ok || h.t * zscale > far) && rs->patch == c[k].patch) {
            st->refinements++; /* the row's seed led astray: the map's own */
            ok = refine(fr, &c[k], NULL, r, &h, &cut);
            st->iterations += h.iters;
        }
        if (ok && (!found || h.t < hit->t)) {
            *hit = (struct bvh_hit){c[k].patch, h.u, h.v, h.t, v3_dot(h.n, h.n) > 0, h.n};
            found = true;
        }
        /* proof of no nearer root of this patch: a root on its seed's sheet (not far behind the
         * fragment), in front of any fold of the patch's outline near the pixel, and not seeded by
         * that outline alone (the pixel off the patch's tessellated image): else a nearer sheet
         * may lie in front */
        const bool resolved = ok && h.t * zscale <= far && h.t * zscale <= c[k].zfold && c[k].zs < c[k].zoutline;
        if (!resolved)
            open_ok[n_open] = ok, open_cut[n_open] = cut, open_zlo[n_open] = c[k].zlo, open[n_open++] = c[k].patch;
    }
    /* a patch meets the ray once at most where the ray is steeper than all its chords, or than all
     * of it and the patch hit together (neighbours across a seam): the root found is then its
     * only one (one that is no hit: it has none), or the one hit is the only point of both, and
     * the patch has none of its own */
    float undecided = rw->dropped[at]; /* least bound of a candidate not resolved */
    int n_left = 0;
    bool seamed = false; /* a patch left open may stand for its neighbour across a seam */
    for (int k = 0; k < n_open; k++)
        if (!((open_ok[k] || open_cut[k]) && bvh_meets_once(fr->exact, open[k], open[k], r->d)) &&
            !(found && !open_ok[k] && bvh_meets_once(fr->exact, open[k], hit->patch, r->d))) {
            undecided = dmin(undecided, open_zlo[k]);
            seamed |= fr->map->seamed[open[k]];
            open[n_left++] = open[k];
        }
    n_open = n_left;
    if (found && !(undecided <= hit->t * zscale))
        return true;
    st->misses++;
    /* only a root in front of the one found matters, and none lies in front of the least depth
     * bound left open (less a margin for the bound's float rounding): a short stretch of ray.
     * Where a seam drew no outline, the pixel's root may be the neighbour's, unlisted and
     * unbounded: all patches, from the eye */
    struct bvh_hit h;
    double tfar = found ? hit->t : INFINITY, tnear = seamed ? 0.0 : dmax(0.0, undecided / zscale * (1.0 - 1e-6));
    bool nearer = seamed || (rw->dropped[at] < INFINITY && rw->dropped[at] <= tfar * zscale)
                      ? bvh_intersect(fr->exact, r, tnear, tfar, &h, &st->iterations)
                      : bvh_intersect_among(fr->exact, r, tnear, tfar, open, n_open, &h, &st->iterations);
    if (nearer)
        *hit = h;
    st->fallback_hits += nearer;
    return found || nearer;
}

static bool ray_box(const struct dray *r, vec3 lo, vec3 hi)
{
    double t0 = 0.0, t1 = INFINITY;
    const double o[3] = {r->o.x, r->o.y, r->o.z}, d[3] = {r->d.x, r->d.y, r->d.z};
    const double l[3] = {lo.x, lo.y, lo.z}, h[3] = {hi.x, hi.y, hi.z};
    for (int k = 0; k < 3; k++) {
        double inv = 1.0 / d[k], a = (l[k] - o[k]) * inv, b = (h[k] - o[k]) * inv;
        if (a > b) {
            double t = a;
            a = b;
            b = t;
        }
        t0 = fmax(t0, a);
        t1 = fmin(t1, b);
    }
    return t0 <= t1;
}

static bool primary_montecarlo(const struct frame *fr, const struct dray *r, uint64_t *rng, struct bvh_hit *hit,
                               struct render_stats *st)
{
    bool found = false;
    for (size_t k = 0; k < fr->ps.n; k++) {
        vec3 lo, hi;
        bezier_bounds(&fr->ps.patches[k], &lo, &hi);
        if (!ray_box(r, lo, hi))
            continue;
        struct solve_hit h;
        st->refinements++;
        bool ok = solve_montecarlo(&fr->ps.patches[k], r, MC_SAMPLES, rng, fr->tol2, &h);
        st->iterations += h.iters;
        if (ok && bezier_kept(&fr->ps.patches[k], h.u, h.v) && (!found || h.t < hit->t)) {
            *hit = (struct bvh_hit){(int)k, h.u, h.v, h.t, v3_dot(h.n, h.n) > 0, h.n};
            found = true;
        }
    }
    return found;
}

/* ---- shading ---------------------------------------------------------------------------- */

/* x^e for the Blinn–Phong exponent: by squaring where e is a whole number (as usual, and
 * validated <= 10000: at most 14 squarings), a fifth the cost of pow. */
static double spec_pow(double x, double e)
{
    unsigned n = e >= 0.0 && e <= 65535.0 ? (unsigned)e : 0; /* no libm floor: a call here */
    if ((double)n != e)
        return pow(x, e);
    double r = 1.0;
    for (; n; n >>= 1, x *= x)
        if (n & 1)
            r *= x;
    return r;
}

/* A pixel of a chunk between its primary ray and its colour. */
struct chunk_px {
    bool ok;
    struct bvh_hit hit;
    struct dray r;
    vec3 n;       /* unit normal, facing the viewer */
    vec3 c;       /* colour so far */
};

/* Diffuse and specular light of l (arriving along unit L, n·L = ndl > 0) at a pixel. */
static vec3 light_term(const struct material *m, const struct light *l, const struct chunk_px *p, vec3 L, double ndl)
{
    vec3 H = v3_norm(v3_sub(L, p->r.d));
    double spec = m->specular * spec_pow(dmax(v3_dot(p->n, H), 0.0), m->shininess);
    return v3_mul(l->color, v3_add(v3_scale(m->color, ndl), v3(spec, spec, spec)));
}

static const struct material *material_of(const struct frame *fr, const struct chunk_px *p)
{
    if (p->hit.patch < 0)
        return &fr->sc->meshes[BVH_HIT_MESH(p->hit.patch)].mat;
    return &fr->sc->objects[fr->ps.patches[p->hit.patch].surface].mat;
}

/* Blinn–Phong with shadow rays for the m pixels of px: each light's shadow rays of the chunk go
 * to the hierarchy together (neighbouring pixels' rays: Embree traces them as packets). */
static void shade_chunk(const struct frame *fr, struct chunk_px *px, int m, struct render_stats *st)
{
    const struct bvh *occ = fr->mesh ? fr->mesh : fr->exact;
    struct bvh_shadow req[SHADE_CHUNK];
    int who[SHADE_CHUNK];
    for (int j = 0; j < m; j++) {
        struct chunk_px *p = &px[j];
        if (!p->ok)
            continue;
        p->n = v3(0, 0, 1);
        if (p->hit.has_normal)
            p->n = p->hit.normal;
        else if (p->hit.patch >= 0)
            bezier_normal(&fr->ps.patches[p->hit.patch], p->hit.u, p->hit.v, &p->n);
        if (v3_dot(p->n, p->r.d) > 0) /* two-sided: face the viewer */
            p->n = v3_scale(p->n, -1.0);
        p->c = v3_scale(material_of(fr, p)->color, AMBIENT);
    }
    for (int k = 0; k < fr->n_lights; k++) {
        const struct light *l = &fr->lights[k];
        bool shadows = fr->sc->shadows && !l->no_shadow;
        int n_req = 0;
        for (int j = 0; j < m; j++) {
            struct chunk_px *p = &px[j];
            if (!p->ok)
                continue;
            vec3 P = v3_mad(p->r.o, p->r.d, p->hit.t);
            vec3 L = fr->toward[k].d; /* a directional light's (unit) */
            double dist = INFINITY;
            if (l->point)
                L = v3_sub(l->v, P), dist = v3_len(L), L = dist > 0 ? v3_scale(L, 1.0 / dist) : L;
            double ndl = v3_dot(p->n, L);
            if (ndl <= 0)
                continue;
            if (!shadows) {
                p->c = v3_add(p->c, light_term(material_of(fr, p), l, p, L, ndl));
                continue;
            }
            struct bvh_shadow *q = &req[n_req];
            vec3 o = v3_mad(P, p->n, (p->hit.patch < 0 ? MESH_SHADOW_EPS : SHADOW_EPS) * fr->diag);
            if (l->point)
                solve_ray_init(&q->r, o, L);
            else
                solve_ray_parallel(&q->r, o, &fr->toward[k]);
            q->from = (struct bvh_origin){p->hit.patch, p->hit.u, p->hit.v};
            q->tnear = 0.0, q->tfar = dist;
            who[n_req++] = j;
        }
        st->rays += n_req;
        st->shadow += n_req;
        bvh_occluded_many(occ, req, (size_t)n_req, &st->shadow_iterations);
        for (int i = 0; i < n_req; i++)
            if (!req[i].blocked) {
                struct chunk_px *p = &px[who[i]];
                p->c = v3_add(p->c, light_term(material_of(fr, p), l, p, req[i].r.d, v3_dot(p->n, req[i].r.d)));
            }
    }
}

/* Writes pixel (x, y) of the frame's buffers. */
/* Writes pixel (x, y): colour c premultiplied by its coverage a (the fraction of its rays that hit),
 * the rest background for an 8-bit picture and for a request that gave one (opaque), else left
 * transparent (RGB 0 where a = 0: premultiplied, as EXR means it); depth and the AOVs from p, the
 * pixel's nearest hit (or none). */
static void put_pixel(struct frame *fr, int x, int y, const struct chunk_px *p, vec3 c, double a)
{
    const struct scene *sc = fr->sc;
    size_t idx = (size_t)y * sc->width + x;
    if (fr->srgb8) {
        unsigned char *px = &fr->srgb8[3 * idx];
        if (a > 0.0) { /* else background, as frame_prepare wrote it */
            c = v3_mad(c, sc->background, 1.0 - a);
            px[0] = srgb8(fr->srgb, (float)c.x), px[1] = srgb8(fr->srgb, (float)c.y), px[2] = srgb8(fr->srgb, (float)c.z);
        }
        return;
    }
    float *px = &fr->rgba[4 * idx];
    if (sc->background_opaque)
        c = v3_mad(c, sc->background, 1.0 - a), a = 1.0;
    vec3 n = p->ok ? p->n : v3(0, 0, 0);
    px[0] = (float)c.x, px[1] = (float)c.y, px[2] = (float)c.z, px[3] = (float)a;
    fr->depth[idx] = p->ok ? (float)p->hit.t : INFINITY;
    if (fr->normal)
        fr->normal[3 * idx] = (float)n.x, fr->normal[3 * idx + 1] = (float)n.y, fr->normal[3 * idx + 2] = (float)n.z;
    if ((fr->uv || fr->id) && p->ok && p->hit.patch < 0) { /* a mesh: barycentric, ids after the objects' */
        if (fr->uv)
            fr->uv[2 * idx] = (float)p->hit.u, fr->uv[2 * idx + 1] = (float)p->hit.v;
        if (fr->id)
            fr->id[idx] = (float)(sc->n_objects + BVH_HIT_MESH(p->hit.patch));
    } else if (fr->uv || fr->id) {
        const struct patch *pt = p->ok ? &fr->ps.patches[p->hit.patch] : NULL;
        if (fr->uv) {
            fr->uv[2 * idx] = p->ok ? (float)(pt->u0 + p->hit.u * (pt->u1 - pt->u0)) : 0.0f;
            fr->uv[2 * idx + 1] = p->ok ? (float)(pt->v0 + p->hit.v * (pt->v1 - pt->v0)) : 0.0f;
        }
        if (fr->id)
            fr->id[idx] = p->ok ? (float)pt->surface : -1.0f;
    }
}

static bool none_listed(const unsigned char *n, int m)
{
    unsigned char any = 0;
    for (int j = 0; j < m; j++)
        any |= n[j];
    return !any;
}

/* Traces and shades the m pixels of row y from x0, each through its point (x + ox, y + oy):
 * method's primary rays (the map's candidates when rw is given: rows y0 on), the row's seed rs
 * carried from chunk to chunk. */
static void trace_chunk(const struct frame *fr, enum render_method method, struct map_rows *rw, int y0, int y, int x0,
                        int m, double ox, double oy, struct chunk_px *px, struct row_seed *rs, uint64_t *rng,
                        struct render_stats *st)
{
    const int W = fr->sc->width;
    st->rays += m;
    st->primary += m;
    /* the chunk's rays first: independent of each other, their square roots and divisions
     * overlap, where each pixel's would wait for the one before to be traced */
    for (int j = 0; j < m; j++) {
        size_t at = (size_t)(y - y0) * W + (size_t)(x0 + j); /* in the band */
        px[j].ok = !rw || rw->n[at]; /* false: background by the map, no ray needed */
        if (px[j].ok) {
            vec3 o, d = camera_ray_at(&fr->cam, x0 + j + ox, y + oy, &o);
            solve_ray_init(&px[j].r, o, d);
        }
    }
    bool any = false;
    for (int j = 0; j < m; j++) {
        struct chunk_px *p = &px[j];
        size_t at = (size_t)(y - y0) * W + (size_t)(x0 + j);
        if (!p->ok) {
            rs->patch = -1;
            continue;
        }
        switch (method) {
        case METHOD_MAP:
        case METHOD_AUTO: p->ok = primary_map(fr, rw, at, rs, &p->r, &p->hit, st); break;
        case METHOD_MONTECARLO: p->ok = primary_montecarlo(fr, &p->r, rng, &p->hit, st); break;
        case METHOD_MESH: p->ok = bvh_intersect(fr->mesh, &p->r, 0.0, INFINITY, &p->hit, &st->iterations); break;
        default: p->ok = bvh_intersect(fr->exact, &p->r, 0.0, INFINITY, &p->hit, &st->iterations); break;
        }
        if (!p->ok)
            rs->patch = -1;
        else if (p->hit.patch == rs->patch)
            *rs = (struct row_seed){p->hit.patch, p->hit.u, p->hit.v, p->hit.u - rs->u, p->hit.v - rs->v};
        else
            *rs = (struct row_seed){p->hit.patch, p->hit.u, p->hit.v, 0.0, 0.0};
        st->hits += p->ok;
        any |= p->ok;
    }
    if (any)
        shade_chunk(fr, px, m, st);
}

static int gcd_int(int a, int b)
{
    while (b) {
        int r = a % b;
        a = b, b = r;
    }
    return a;
}

/* Sample s of n within a pixel: n rooks (one in each column and each row of an n x n grid, the
 * rows a coprime stride apart), so an edge of any slope sees n levels of coverage. */
static void rook(int s, int n, double *ox, double *oy)
{
    int stride = (int)(0.618 * n + 0.5);
    while (stride > 1 && gcd_int(n, stride) != 1)
        stride--;
    *ox = (s + 0.5) / n;
    *oy = ((long)s * (stride > 0 ? stride : 1) % n + 0.5) / n;
}

/* Rows [y0, y1) with samples rays a pixel: the hierarchy's (the map's candidates are the pixel
 * centres'), colours averaged, coverage the fraction that hit, depth and AOVs of the nearest hit. */
static void band_sampled(struct frame *fr, enum render_method method, int y0, int y1, struct render_stats *st)
{
    const int W = fr->sc->width, n = fr->sc->samples;
    if (method == METHOD_MAP || method == METHOD_AUTO)
        method = METHOD_BVH;
    uint64_t rng = 0x9E3779B97F4A7C15ull ^ (uint64_t)(y0 + 1) * 0xBF58476D1CE4E5B9ull;
    struct chunk_px px[SHADE_CHUNK], near[SHADE_CHUNK];
    vec3 sum[SHADE_CHUNK];
    int hits[SHADE_CHUNK];
    for (int y = y0; y < y1; y++)
        for (int x0 = 0; x0 < W; x0 += SHADE_CHUNK) {
            int m = W - x0 < SHADE_CHUNK ? W - x0 : SHADE_CHUNK;
            for (int j = 0; j < m; j++)
                sum[j] = v3(0, 0, 0), hits[j] = 0, near[j].ok = false;
            for (int s = 0; s < n; s++) {
                double ox, oy;
                rook(s, n, &ox, &oy);
                struct row_seed rs = {.patch = -1};
                trace_chunk(fr, method, NULL, y0, y, x0, m, ox, oy, px, &rs, &rng, st);
                for (int j = 0; j < m; j++)
                    if (px[j].ok) {
                        sum[j] = v3_add(sum[j], px[j].c), hits[j]++;
                        if (!near[j].ok || px[j].hit.t < near[j].hit.t)
                            near[j] = px[j];
                    }
            }
            for (int j = 0; j < m; j++)
                put_pixel(fr, x0 + j, y, &near[j], v3_scale(sum[j], 1.0 / n), (double)hits[j] / n);
        }
}

void frame_band(struct frame *fr, int y0, int y1, struct render_stats *st)
{
    const struct scene *sc = fr->sc;
    const int W = sc->width;
    enum render_method method = sc->method;
    if ((method == METHOD_MAP || method == METHOD_AUTO) && (!fr->map || !fr->map->complete))
        method = METHOD_BVH; /* too large for a map, or the eye inside the scene's hull */
    if (fr->srgb8) { /* the rows start as background: only the pixels something covers are written */
        unsigned char *row = fr->srgb8 + 3 * (size_t)W * y0, *end = fr->srgb8 + 3 * (size_t)W * y1;
        for (; row < end; row += sizeof fr->bg8)
            memcpy(row, fr->bg8, (size_t)(end - row) < sizeof fr->bg8 ? (size_t)(end - row) : sizeof fr->bg8);
    }
    if (sc->samples > 1) {
        band_sampled(fr, method, y0, y1, st);
        return;
    }
    struct map_rows rw = {0};
    if ((method == METHOD_MAP || method == METHOD_AUTO) && map_raster_rows(fr->map, y0, y1, &rw))
        method = METHOD_BVH; /* no memory for the band's candidates: exact all the same */
    const bool use_map = method == METHOD_MAP || method == METHOD_AUTO;
    uint64_t rng = 0x9E3779B97F4A7C15ull ^ (uint64_t)(y0 + 1) * 0xBF58476D1CE4E5B9ull;
    struct chunk_px px[SHADE_CHUNK];
    for (int y = y0; y < y1; y++) {
        struct row_seed rs = {.patch = -1};
        for (int x0 = 0; x0 < W; x0 += SHADE_CHUNK) {
            int m = W - x0 < SHADE_CHUNK ? W - x0 : SHADE_CHUNK;
            if (use_map && fr->srgb8 && none_listed(&rw.n[(size_t)(y - y0) * W + x0], m)) {
                st->rays += m;
                st->primary += m;
                rs.patch = -1; /* background alone, by the map (most chunks of a frame): written already */
                continue;
            }
            trace_chunk(fr, method, use_map ? &rw : NULL, y0, y, x0, m, 0.5, 0.5, px, &rs, &rng, st);
            for (int j = 0; j < m; j++)
                put_pixel(fr, x0 + j, y, &px[j], px[j].ok ? px[j].c : v3(0, 0, 0), px[j].ok);
        }
    }
    map_rows_free(&rw);
}

void frame_image(const struct frame *fr, struct frame_image *img)
{
    img->width = fr->sc->width;
    img->height = fr->sc->height;
    img->rgba = fr->rgba;
    img->depth = fr->depth;
    img->normal = fr->normal;
    img->uv = fr->uv;
    img->id = fr->id;
    img->srgb8 = fr->srgb8;
}

double frame_prepare_ms(const struct frame *fr) { return fr->prepare_ms; }

const struct bvh *frame_hierarchy(const struct frame *fr) { return fr->exact; }

void frame_bounds(const struct frame *fr, double lo[3], double hi[3])
{
    lo[0] = fr->lo.x, lo[1] = fr->lo.y, lo[2] = fr->lo.z;
    hi[0] = fr->hi.x, hi[1] = fr->hi.y, hi[2] = fr->hi.z;
}
size_t frame_n_patches(const struct frame *fr) { return fr->ps.n; }
