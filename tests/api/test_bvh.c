/* test_bvh.c - the exact hierarchy: rays aimed at surface points find them (nearest first), and
 * skipping a shadow ray's origin leaf by its normal cone never changes an occlusion answer. */
#include "../../api/scene_io.h"
#include "../../core/trace/bvh.h"
#include "../unit.h"
#include "contour_scene.h"

#include <stdlib.h>

static struct bvh_device *dev;

static int load(const char *name, struct scene *sc, struct patch_set *ps)
{
    size_t len;
    memset(ps, 0, sizeof *ps);
    char *buf = unit_data("scenes", name, &len);
    if (!buf)
        return -1;
    enum image_format img;
    int rc = scene_parse(buf, len, SCENE_UNKNOWN, sc, &img, NULL);
    free(buf);
    for (int k = 0; !rc && k < sc->n_objects; k++)
        rc = nurbs_extract(&sc->objects[k].surf, k, ps);
    nurbs_patches_fix(ps);
    return rc;
}

static double rnd(uint64_t *s)
{
    *s ^= *s << 13, *s ^= *s >> 7, *s ^= *s << 17;
    return (double)(*s >> 11) / 9007199254740992.0;
}

/* From points all over the teapot, the cup, a duck, the IGES mug (rational patches: their cones
 * and chord bounds from the tangents' and normals' numerators) and the heart's contour model (half of them
 * within a hundredth of a patch's edge, where the neighbour's leaves across the seam hold the
 * origin), toward random directions on the outer side: the answer with the origin's leaf, its
 * neighbourhood and its seam neighbour's leaves skipped equals the full search, and a good share
 * of rays is blocked. */
TEST(origin_skip_never_changes_occlusion)
{
    const char *names[] = {"teapot.json", "teacup.json", "duck1.nurbs", "mug_solid.igs", "dicompyler_heart.json"};
    for (int f = 0; f < 5; f++) {
        struct scene sc = {0};
        struct patch_set ps = {0};
        struct contour_scene heart = {0};
        if (f < 4)
            CHECK(load(names[f], &sc, &ps) == 0);
        else
            CHECK(contour_scene_load(names[f], &heart) && scene_patches(&heart.sc, &ps, NULL) == 0);
        if (!ps.patches) { /* no data: nothing to trace */
            contour_scene_free(&heart);
            continue;
        }
        struct bvh *b;
        CHECK(bvh_build_patches(dev, ps.patches, ps.n, 1e-20, &b, NULL) == 0);
        uint64_t s = 88172645463325252ull;
        long blocked = 0, differ = 0, n = 0;
        const int per_patch = f < 3 ? 400 : f == 3 ? 4000 : 40;
        for (size_t k = 0; k < ps.n; k++)
            for (int j = 0; j < per_patch; j++, n++) {
                double u = rnd(&s), v = rnd(&s);
                if (j % 2) { /* near an edge */
                    double w = 0.01 * rnd(&s);
                    int e = (int)(4 * rnd(&s)) & 3;
                    *(e < 2 ? &u : &v) = e & 1 ? 1 - w : w;
                }
                vec3 P, N, d;
                bezier_eval(&ps.patches[k], u, v, &P, NULL, NULL);
                if (!bezier_normal(&ps.patches[k], u, v, &N))
                    continue;
                do
                    d = v3(rnd(&s) * 2 - 1, rnd(&s) * 2 - 1, rnd(&s) * 2 - 1);
                while (v3_len(d) > 1 || v3_len(d) < 0.1);
                if (v3_dot(d, N) < 0) /* leave on the side the normal (or its flip) faces */
                    N = v3_scale(N, -1);
                d = v3_norm(d);
                if (v3_dot(d, N) < 0)
                    d = v3_scale(d, -1);
                struct dray r;
                solve_ray_init(&r, v3_mad(P, N, 1e-7 * (f < 3 ? 7.0 : 150.0)), d); /* (sizes 8 and 170) */
                const struct bvh_origin from = {(int)k, u, v};
                bool a = bvh_occluded(b, &r, &from, 0.0, INFINITY, NULL);
                bool c = bvh_occluded(b, &r, NULL, 0.0, INFINITY, NULL);
                blocked += c;
                differ += a != c;
            }
        fprintf(stderr, "  %s: %ld rays, %ld blocked, %ld answers differ\n", names[f], n, blocked, differ);
        CHECK(differ == 0);
        CHECK(blocked > n / 20);
        bvh_free(b);
        nurbs_patch_set_free(&ps);
        if (f < 4)
            scene_free(&sc);
        contour_scene_free(&heart);
    }
}

/* Rays from outside aimed at sampled points find them, or something nearer. */
TEST(intersect_finds_sampled_points)
{
    struct scene sc;
    struct patch_set ps;
    CHECK(load("teapot.json", &sc, &ps) == 0);
    if (!ps.patches)
        return; /* no data: nothing to trace */
    struct bvh *b;
    const double tol = 1e-11; /* root residual: a hit's distance is within about that of the truth */
    CHECK(bvh_build_patches(dev, ps.patches, ps.n, tol * tol, &b, NULL) == 0);
    CHECK(bvh_n_leaves(b) >= ps.n);
    uint64_t s = 12345;
    long exact = 0, nearer = 0, missed = 0;
    for (size_t k = 0; k < ps.n; k++)
        for (int j = 0; j < 200; j++) {
            double u = rnd(&s), v = rnd(&s);
            vec3 P, N;
            bezier_eval(&ps.patches[k], u, v, &P, NULL, NULL);
            if (!bezier_normal(&ps.patches[k], u, v, &N))
                continue;
            vec3 d = v3_norm(v3_add(v3_scale(N, -1), v3(0.3 * (rnd(&s) - 0.5), 0.3 * (rnd(&s) - 0.5), 0)));
            struct dray r;
            solve_ray_init(&r, v3_mad(P, d, -0.05), d);
            struct bvh_hit h;
            if (!bvh_intersect(b, &r, 0.0, INFINITY, &h, NULL)) {
                missed++;
                continue;
            }
            if (fabs(h.t - 0.05) < 2 * tol)
                exact++;
            else if (h.t < 0.05)
                nearer++; /* another part of the teapot is in front */
            else
                missed++;
        }
    fprintf(stderr, "  exact %ld, something nearer %ld, missed %ld\n", exact, nearer, missed);
    CHECK(missed == 0);
    CHECK(exact > 3000);
    bvh_free(b);
    nurbs_patch_set_free(&ps);
    scene_free(&sc);
}

/* A point of patch a, or (half the time, when it has one) of its neighbour across seam e. */
static vec3 seam_point(const struct patch_set *ps, const struct bvh *b, int a, int e, uint64_t *s, int *on)
{
    int other = bvh_seam(b, a, e);
    *on = other >= 0 && rnd(s) < 0.5 ? other : a;
    vec3 P;
    double u = rnd(s), v = rnd(s);
    if (rnd(s) < 0.5) /* near the seam, where the two patches' points come closest */
        u = e < 2 ? (*on == a) == (e == 1) ? 1 - 0.01 * u : 0.01 * u : u,
        v = e >= 2 ? (*on == a) == (e == 3) ? 1 - 0.01 * v : 0.01 * v : v;
    bezier_eval(&ps->patches[*on], u, v, &P, NULL, NULL);
    return P;
}

/* The bound that lets a ray skip a patch or a seam's pair of patches never holds along a chord of
 * them (a line through two of their points): pairs of points near seams and anywhere, on the
 * teapot (large curved patches: the bound seldom holds), the heart's contour model (where it
 * holds along a third of the normals: sheared patches' bounds are loose) and the IGES mug
 * (rational patches). */
TEST(meets_once_never_along_a_chord)
{
    for (int f = 0; f < 3; f++) {
        struct scene sc;
        struct patch_set ps = {0};
        struct contour_scene heart = {0};
        if (f != 1)
            CHECK(load(f ? "mug_solid.igs" : "teapot.json", &sc, &ps) == 0);
        else
            CHECK(contour_scene_load("dicompyler_heart.json", &heart) && scene_patches(&heart.sc, &ps, NULL) == 0);
        if (!ps.patches) { /* no data: nothing to trace */
            contour_scene_free(&heart);
            continue;
        }
        struct bvh *b;
        CHECK(bvh_build_patches(dev, ps.patches, ps.n, 1e-20, &b, NULL) == 0);
        uint64_t s = 4242;
        long seams = 0, chords = 0, wrong = 0, normals = 0, held = 0;
        const int per_seam = f != 1 ? 2000 : 20;
        for (size_t k = 0; k < ps.n; k++)
            for (int e = 0; e < 4; e++) {
                int other = bvh_seam(b, (int)k, e);
                if (other < 0)
                    continue;
                seams++;
                CHECK(bvh_seam(b, other, e ^ 1) == (int)k);
                for (int j = 0; j < per_seam; j++) {
                    int on1, on2;
                    vec3 p1 = seam_point(&ps, b, (int)k, e, &s, &on1), p2 = seam_point(&ps, b, (int)k, e, &s, &on2);
                    vec3 c = v3_sub(p2, p1);
                    if (!(v3_len(c) > 0))
                        continue;
                    chords++;
                    c = v3_norm(c);
                    wrong += bvh_meets_once(b, (int)k, other, c) || (on1 == on2 && bvh_meets_once(b, on1, on1, c));
                    vec3 n;
                    if (bezier_normal(&ps.patches[on1], rnd(&s), rnd(&s), &n))
                        normals++, held += bvh_meets_once(b, (int)k, other, n);
                }
            }
        fprintf(stderr, "  %s: %ld seams, %ld chords, the bound held along %ld; along normals %ld of %ld\n",
                f == 1 ? "heart" : f ? "mug" : "teapot", seams, chords, wrong, held, normals);
        CHECK(seams >= (f == 0 ? 40 : f == 1 ? 10000 : 8));
        CHECK(wrong == 0);
        CHECK(f != 1 || held > normals / 4);
        bvh_free(b);
        nurbs_patch_set_free(&ps);
        if (f != 1)
            scene_free(&sc);
        contour_scene_free(&heart);
    }
}

int main(void)
{
    dev = bvh_device_new(1, NULL);
    RUN(origin_skip_never_changes_occlusion);
    RUN(intersect_finds_sampled_points);
    RUN(meets_once_never_along_a_chord);
    bvh_device_free(dev);
    UNIT_END();
}
