/* test_map.c - the preliminary-value map's seams: two patches that share an edge are sampled at
 * the same parameters there and draw no outline where the surface goes on, an outline where it
 * folds; every pixel either covers gets a candidate; and joining seams grows no patch's grid past
 * its bound. */
#include "../../../core/trace/bvh.h"
#include "../../../core/trace/map.h"
#include "../../unit.h"

#include <stdlib.h>

static struct bvh_device *dev;

/* Bicubic patch k of a strip along x: its control points on z = h(x, y) sampled at thirds (h
 * bilinear along each patch: exact), x from x0 + k w to x0 + (k+1) w, y from 0 to 1. */
static void strip_patch(struct patch *pt, double (*cw)[4], double x0, double w, int k, double (*h)(double, double))
{
    for (int i = 0; i < 4; i++)
        for (int j = 0; j < 4; j++) {
            double x = x0 + (k + i / 3.0) * w, y = j / 3.0;
            cw[i * 4 + j][0] = x, cw[i * 4 + j][1] = y, cw[i * 4 + j][2] = h(x, y), cw[i * 4 + j][3] = 1.0;
        }
    *pt = (struct patch){.p = 3, .q = 3, .cw = cw, .u1 = 1, .v1 = 1};
    bezier_second_bounds(pt);
}

static double bowl(double x, double y);
static double wall(double x, double y) { return (x < 0 ? 0.0 : 3.0 * x) + bowl(x, y); } /* rises at x = 0 */
static double bowl(double x, double y) { return (void)x, 0.6 * (y - 0.5) * (y - 0.5); }
/* a bowl for x <= 0 flattening to a plane by x = 0.02 */
static double bowl_edge(double x, double y) { return bowl(x, y) * (x <= 0 ? 1.0 : x >= 0.02 ? 0.0 : 1.0 - x / 0.02); }

/* Candidates that carry a fold's depth, in the frame's rows. */
static long fold_candidates(const struct map_rows *rw, int W, int H)
{
    long n = 0;
    for (int i = 0; i < W * H; i++)
        for (int k = 0; k < rw->n[i]; k++)
            n += isfinite(rw->cand[i * MAP_CANDS + k].zfold);
    return n;
}

static struct map *build(const struct patch *ps, size_t n, const struct bvh *seams, const struct camera *cam)
{
    struct map *m = NULL;
    struct sf_err err = {0};
    CHECK(map_build(ps, n, seams, cam, &m, &err) == 0);
    return m;
}

/* Every pixel centre in the frame that the map lists something for, against the one without seams
 * (each border an outline): the seams' map covers every pixel the strip's patches cover (no crack
 * between the two sides' triangles), and lists fewer candidates in all. */
TEST(seam_covers_without_outline)
{
    double cw[2][16][4];
    struct patch ps[2];
    for (int k = 0; k < 2; k++)
        strip_patch(&ps[k], cw[k], -1.0, 1.0, k, bowl);
    struct bvh *b;
    REQUIRE(bvh_build_patches(dev, ps, 2, 1e-20, &b, NULL) == 0);
    CHECK(bvh_seam(b, 0, 1) == 1 && bvh_seam(b, 1, 0) == 0 && bvh_seam(b, 0, 0) == -1 && bvh_seam(b, 0, 3) == -1);
    struct camera cam;
    camera_init(&cam, v3(0.1, 0.45, 1.2), v3(0.0, 0.5, 0.0), v3(0, 1, 0), 60, 160, 120);
    struct map *with = build(ps, 2, b, &cam), *without = build(ps, 2, NULL, &cam);
    REQUIRE(with && without);
    CHECK(with->seamed[0] && with->seamed[1] && !without->seamed[0]);
    CHECK(with->grid[0][1] == with->grid[1][1]); /* the seam's count, both sides */
    struct map_rows a = {0}, c = {0};
    REQUIRE(map_raster_rows(with, 0, cam.H, &a) == 0 && map_raster_rows(without, 0, cam.H, &c) == 0);
    long covered = 0, lost = 0, cands_with = 0, cands_without = 0;
    for (int i = 0; i < cam.W * cam.H; i++) {
        covered += c.n[i] > 0;
        lost += c.n[i] > 0 && a.n[i] == 0;
        cands_with += a.n[i], cands_without += c.n[i];
    }
    fprintf(stderr, "  %ld pixels covered, %ld lost; candidates %ld with seams, %ld without\n", covered, lost,
            cands_with, cands_without);
    CHECK(covered > cam.W * cam.H / 4 && lost == 0 && cands_with < cands_without);
    map_rows_free(&a), map_rows_free(&c);
    map_free(with), map_free(without);
    bvh_free(b);
}

/* Where the surface folds at a seam (a floor, and a wall rising from it seen from behind: their
 * triangles turn opposite ways on screen) the seam stays an outline, a fold the tracer trusts no
 * root behind; on the strip that goes on (a bowl) there is none. */
TEST(seam_folds_keep_outline)
{
    for (int f = 0; f < 2; f++) {
        double cw[2][16][4];
        struct patch ps[2];
        for (int k = 0; k < 2; k++)
            strip_patch(&ps[k], cw[k], -1.0, 1.0, k, f ? wall : bowl);
        struct bvh *b;
        REQUIRE(bvh_build_patches(dev, ps, 2, 1e-20, &b, NULL) == 0);
        struct camera cam;
        camera_init(&cam, v3(2.5, 0.5, 2.5), v3(0.0, 0.5, 0.0), v3(0, 1, 0), 60, 160, 120);
        struct map *m = build(ps, 2, b, &cam);
        struct map_rows rw = {0};
        REQUIRE(m && map_raster_rows(m, 0, cam.H, &rw) == 0);
        long folds = fold_candidates(&rw, cam.W, cam.H);
        fprintf(stderr, "  %s: %ld candidates by a fold\n", f ? "wall" : "bowl", folds);
        CHECK(f ? folds > 20 : folds == 0);
        map_rows_free(&rw);
        map_free(m);
        bvh_free(b);
    }
}

/* A chain of narrow patches beside a wide curved one close to the eye: joining the seams takes a
 * chain's finest count only up to MAP_SEAM_GROW times a patch's own (the narrow ones keep theirs,
 * and their seam with the wide one stays an outline), so the map grows by a bounded factor. */
TEST(seam_grids_grow_bounded)
{
    enum { N = 12 };
    double cw[N][16][4];
    struct patch ps[N];
    strip_patch(&ps[0], cw[0], -1.0, 1.0, 0, bowl_edge);
    for (int k = 1; k < N; k++)
        strip_patch(&ps[k], cw[k], 0.0 - 0.02, 0.02, k, bowl_edge);
    struct bvh *b;
    REQUIRE(bvh_build_patches(dev, ps, N, 1e-20, &b, NULL) == 0);
    CHECK(bvh_seam(b, 0, 1) == 1 && bvh_seam(b, 5, 1) == 6);
    struct camera cam;
    camera_init(&cam, v3(-0.5, 0.5, 0.4), v3(-0.5, 0.5, 0.0), v3(0, 1, 0), 60, 800, 600);
    struct map *with = build(ps, N, b, &cam), *own = build(ps, N, NULL, &cam);
    REQUIRE(with && own);
    fprintf(stderr, "  v counts: wide %d (own %d), narrow %d (own %d)\n", with->grid[0][1], own->grid[0][1],
            with->grid[6][1], own->grid[6][1]);
    CHECK(own->grid[0][1] > 4 * own->grid[6][1]); /* the bound binds */
    for (int k = 0; k < N; k++)
        CHECK(with->grid[k][1] <= 4 * own->grid[k][1] && with->grid[k][0] <= 4 * own->grid[k][0]);
    CHECK(with->grid[6][1] == with->grid[7][1]);
    map_free(with), map_free(own);
    bvh_free(b);
}

int main(void)
{
    dev = bvh_device_new(1, NULL);
    RUN(seam_covers_without_outline);
    RUN(seam_folds_keep_outline);
    RUN(seam_grids_grow_bounded);
    bvh_device_free(dev);
    UNIT_END();
}
