/* test_render.c - whole frames. The teapot at 1024x768 (eye [7,-10,6], target [0.2,0,1.3], up z,
 * fov 30°) by the exact methods against a dense tessellation of the same patches: zero missed
 * interior pixels, depth within 1e-3 relative; map, bvh and mesh agree. Every shared scene renders
 * through every exact method with the same coverage. Bad scenes fail with a pointer. */
#include "../../api/scene_io.h"
#include "../../core/trace/render.h"
#include "../../core/trace/srgb.h"
#include "../unit.h"
#include "contour_scene.h"

#include <stdlib.h>

static struct bvh_device *dev;

/* The mesh method's chord error where its frame is the reference: a dense tessellation */
#define DENSE_MESH 2e-6

/* Renders a parsed scene with the given method and size (the scene keeps its objects), the mesh
 * method's chord error mesh_tol (0: the scene's own); returns a malloc'd depth buffer. */
static float *scene_depth(struct scene *sc, enum render_method m, double mesh_tol, int W, int H, bool teapot_camera,
                          struct render_stats *st)
{
    sc->width = W, sc->height = H, sc->method = m, sc->shadows = false;
    if (mesh_tol > 0)
        sc->mesh_tolerance = mesh_tol;
    if (teapot_camera) {
        sc->has_camera = true;
        sc->eye = v3(7, -10, 6), sc->target = v3(0.2, 0, 1.3), sc->up = v3(0, 0, 1), sc->fov_deg = 30;
    }
    struct frame *fr;
    struct sf_err err = {0};
    float *depth = NULL;
    if (frame_prepare(sc, dev, &fr, &err) == 0) {
        struct render_stats s = {0};
        frame_band(fr, 0, H, &s);
        if (st)
            *st = s;
        struct frame_image im;
        frame_image(fr, &im);
        depth = malloc(sizeof *depth * (size_t)W * H);
        memcpy(depth, im.depth, sizeof *depth * (size_t)W * H);
        frame_free(fr);
    } else {
        fprintf(stderr, "  prepare: %s\n", err.message);
    }
    return depth;
}

/* Parses shared scene file `name` into *sc; false (with a message) when it cannot. */
static bool load_scene(const char *name, struct scene *sc)
{
    size_t len = 0;
    char *buf = unit_data("scenes", name, &len);
    if (!buf)
        return false;
    enum image_format img;
    struct sf_err err = {0};
    int rc = scene_parse(buf, len, SCENE_UNKNOWN, sc, &img, &err);
    free(buf);
    if (rc)
        fprintf(stderr, "  %s: %s at %s\n", name, err.message, err.pointer);
    return rc == 0;
}

/* Renders scene file `name` with the given method and size; returns a malloc'd depth buffer. */
static float *render_depth(const char *name, enum render_method m, double mesh_tol, int W, int H,
                           bool teapot_camera, struct render_stats *st)
{
    struct scene sc;
    if (!load_scene(name, &sc))
        return NULL;
    float *depth = scene_depth(&sc, m, mesh_tol, W, H, teapot_camera, st);
    scene_free(&sc);
    return depth;
}

struct compare {
    long interior;   /* reference pixels whose 3x3 neighbourhood is all hit */
    long missed;     /* ... that the method under test missed */
    long smooth;     /* interior pixels without a depth edge nearby */
    long depth_off;  /* ... where depth differs by more than 1e-3 relative */
    long extra;      /* pixels the method hits and the reference misses with all 8 neighbours */
};

static struct compare compare(const float *ref, const float *got, int W, int H)
{
    struct compare c = {0};
    for (int y = 1; y < H - 1; y++)
        for (int x = 1; x < W - 1; x++) {
            bool all = true, none = true;
            float lo = INFINITY, hi = 0;
            for (int dy = -1; dy <= 1; dy++)
                for (int dx = -1; dx <= 1; dx++) {
                    float d = ref[(y + dy) * W + x + dx];
                    all &= isfinite(d);
                    none &= !isfinite(d);
                    if (isfinite(d))
                        lo = fminf(lo, d), hi = fmaxf(hi, d);
                }
            size_t i = (size_t)y * W + x;
            if (none && isfinite(got[i]))
                c.extra++;
            if (!all)
                continue;
            c.interior++;
            if (!isfinite(got[i])) {
                c.missed++;
                continue;
            }
            if (hi - lo < 0.005f * lo) { /* no depth edge (a thin lip is a 1 % edge) */
                c.smooth++;
                if (fabsf(got[i] - ref[i]) > 1e-3f * ref[i]) {
                    c.depth_off++;
                    if (getenv("SURFD_TEST_VERBOSE"))
                        fprintf(stderr, "    depth off at (%d, %d): %.6f vs mesh %.6f\n", x, y, got[i], ref[i]);
                }
            }
        }
    return c;
}

TEST(teapot_exact_methods_against_dense_mesh)
{
    const int W = 1024, H = 768;
    struct render_stats st;
    float *ref = render_depth("teapot.json", METHOD_MESH, DENSE_MESH, W, H, true, NULL);
    CHECK(ref != NULL);
    if (!ref)
        return;
    const enum render_method methods[] = {METHOD_AUTO, METHOD_BVH, METHOD_MAP};
    for (int k = 0; k < 3; k++) {
        float *got = render_depth("teapot.json", methods[k], DENSE_MESH, W, H, true, &st);
        CHECK(got != NULL);
        if (!got)
            continue;
        struct compare c = compare(ref, got, W, H);
        fprintf(stderr, "  %-5s interior %ld missed %ld smooth %ld depth_off %ld extra %ld (fallback %ld)\n",
                scene_method_name(methods[k]), c.interior, c.missed, c.smooth, c.depth_off, c.extra, st.misses);
        CHECK(c.interior > 100000);
        CHECK(c.missed == 0);
        CHECK(c.depth_off == 0);
        CHECK(c.extra == 0);
        free(got);
    }
    free(ref);
}

/* Every shared scene (the IGES mug: trimmed rational patches) through bvh, auto, map and mesh: away
 * from silhouettes (where a grazing root may fall either side of a pixel centre) the same pixels hit
 * at the same depths. The mesh at the scene's own chord error (1e-4 of its size, 1e-3 of the depth
 * being the check): not the dense reference, which took a minute of this test under the sanitizers. */
TEST(shared_scenes_agree_across_methods)
{
    const char *names[] = {"teacup.json", "teaspoon.bpt", "duck1.nurbs", "duck2.nurbs", "duck3.nurbs", "teapot.bpt",
                           "mug_solid.igs"};
    for (size_t n = 0; n < sizeof names / sizeof *names; n++) {
        const int W = 240, H = 180;
        struct render_stats st;
        float *ref = render_depth(names[n], METHOD_BVH, 0, W, H, false, &st);
        CHECK(ref != NULL);
        if (!ref)
            continue;
        CHECK(st.hits > W * H / 50); /* auto-framing puts the object in view */
        const enum render_method methods[] = {METHOD_AUTO, METHOD_MAP, METHOD_MESH};
        for (int k = 0; k < 3; k++) {
            float *got = render_depth(names[n], methods[k], 0, W, H, false, NULL);
            if (!got) {
                CHECK(got != NULL);
                continue;
            }
            struct compare c = compare(ref, got, W, H);
            if (c.missed || c.depth_off || c.extra)
                fprintf(stderr, "  %s %s: missed %ld depth_off %ld extra %ld of %ld interior\n", names[n],
                        scene_method_name(methods[k]), c.missed, c.depth_off, c.extra, c.interior);
            CHECK(c.missed == 0 && c.depth_off == 0 && c.extra == 0);
            free(got);
        }
        free(ref);
    }
}

/* A contour model (thousands of small patches, some of them slivers a hundredth of a millimetre wide
 * where neighbouring curves' breakpoints nearly meet): auto and bvh against a dense tessellation. */
TEST(contour_model_exact)
{
    struct contour_scene c;
    bool ok = contour_scene_load("synthetic_ellipsoid.json", &c);
    CHECK(ok);
    const int W = 400, H = 300;
    float *ref = ok ? scene_depth(&c.sc, METHOD_MESH, DENSE_MESH, W, H, false, NULL) : NULL;
    const enum render_method methods[] = {METHOD_AUTO, METHOD_BVH};
    for (int k = 0; k < 2 && ref; k++) {
        float *got = scene_depth(&c.sc, methods[k], DENSE_MESH, W, H, false, NULL);
        struct compare cmp = compare(ref, got, W, H);
        fprintf(stderr, "  %-5s interior %ld missed %ld depth_off %ld extra %ld\n", scene_method_name(methods[k]),
                cmp.interior, cmp.missed, cmp.depth_off, cmp.extra);
        CHECK(cmp.interior > 20000 && cmp.missed == 0 && cmp.depth_off == 0 && cmp.extra == 0);
        free(got);
    }
    free(ref);
    contour_scene_free(&c);
}

/* Auto against the hierarchy on sc at W x H, pixel by pixel: the pixels bvh hits, those auto misses,
 * those where its root lies farther or nearer (beyond 1e-5 relative). */
struct against_bvh {
    long hit, missed, farther, more;
};

static struct against_bvh auto_against_bvh(struct scene *sc, int W, int H, struct render_stats *st)
{
    struct against_bvh a = {0};
    float *bvh = scene_depth(sc, METHOD_BVH, DENSE_MESH, W, H, false, NULL);
    float *got = scene_depth(sc, METHOD_AUTO, DENSE_MESH, W, H, false, st);
    CHECK(bvh && got);
    for (int i = 0; bvh && got && i < W * H; i++) {
        a.hit += isfinite(bvh[i]);
        a.missed += isfinite(bvh[i]) && !isfinite(got[i]);
        a.farther += isfinite(bvh[i]) && got[i] - bvh[i] > 1e-5f * bvh[i];
        a.more += isfinite(got[i]) && !(got[i] - bvh[i] > -1e-5f * got[i]);
    }
    free(bvh);
    free(got);
    return a;
}

/* The heart's contour model (7 587 patches, most of them meeting their neighbours along whole
 * edges, where the map draws no outline): from four sides auto finds every root the hierarchy
 * finds, none farther. Its roots are roots (their residual within tolerance), and it finds a few
 * the hierarchy misses where the ray grazes a fold (one pixel of these four views, and before the
 * seams went without outline another nearer by 0.05 mm): a nearer root is allowed twice a view. */
TEST(heart_model_auto_equals_bvh)
{
    struct contour_scene c;
    bool ok = contour_scene_load("dicompyler_heart.json", &c);
    CHECK(ok);
    struct scene *sc = &c.sc;
    const int W = 720, H = 720; /* 64 pixels a patch: auto takes the map (AUTO_MAP_PIXELS_PER_PATCH) */
    const double azimuths[] = {0, 70, 160, 250};
    for (int k = 0; k < 4 && ok; k++) {
        sc->azimuth_deg = azimuths[k], sc->elevation_deg = 20;
        struct render_stats st = {0};
        struct against_bvh a = auto_against_bvh(sc, W, H, &st);
        fprintf(stderr, "  azimuth %3.0f: %ld pixels hit, auto missed %ld, farther at %ld, nearer at %ld (searched %ld)\n",
                azimuths[k], a.hit, a.missed, a.farther, a.more, st.misses);
        CHECK(a.hit > W * H / 8 && a.missed == 0 && a.farther == 0 && a.more <= 2 && st.refinements > a.hit);
    }
    contour_scene_free(&c);
}

/* The IGES mug (13 trimmed rational surfaces) from three sides: auto finds every root the hierarchy
 * finds, none farther (a nearer one twice a view at most: a grazing root the hierarchy misses, as
 * on the heart). A pixel whose candidate's root the trims cut away is settled without the
 * hierarchy only where the ray meets that patch once (its chord bound). */
TEST(trimmed_mug_auto_equals_bvh)
{
    struct scene sc;
    if (!load_scene("mug_solid.igs", &sc)) {
        CHECK(!"mug_solid.igs loads");
        return;
    }
    const int W = 720, H = 720;
    const vec3 eyes[] = {v3(250, -300, 220), v3(-300, -120, 60), v3(80, 260, -200)};
    for (int k = 0; k < 3; k++) {
        sc.has_camera = true;
        sc.eye = eyes[k], sc.target = v3(0, 0, 40), sc.up = v3(0, 0, 1), sc.fov_deg = 30;
        struct render_stats st = {0};
        struct against_bvh a = auto_against_bvh(&sc, W, H, &st);
        fprintf(stderr, "  eye %d: %ld pixels hit, auto missed %ld, farther at %ld, nearer at %ld (searched %ld)\n", k,
                a.hit, a.missed, a.farther, a.more, st.misses);
        CHECK(a.hit > W * H / 10 && a.missed == 0 && a.farther == 0 && a.more <= 2);
    }
    scene_free(&sc);
}

/* Bad scenes get an error naming the object and field, never a crash. */
TEST(bad_scenes_fail_with_pointer)
{
    struct {
        const char *json;
        int code;
        const char *pointer;
    } cases[] = {
        {"{\"objects\":[{\"type\":\"bspline\",\"degree\":[2,2],\"size\":[3,3],\"knots_u\":[0,0,0,1,0.5,1],"
         "\"knots_v\":[0,0,0,1,1,1],\"points\":[[0,0,0],[1,0,0],[2,0,0],[0,1,0],[1,1,1],[2,1,0],[0,2,0],[1,2,0],[2,2,0]]}]}",
         SF_EINVAL, "/objects/0/knots_u/4"},
        {"{\"objects\":[{\"type\":\"nurbs\",\"degree\":[1,1],\"size\":[2,2],\"knots_u\":[0,0,1,1],\"knots_v\":[0,0,1,1],"
         "\"points\":[[0,0,0],[1,0,0],[0,1,0],[1,1,0]],\"weights\":[1,1,0,1]}]}",
         SF_EINVAL, "/objects/0/weights/2"},
        {"{\"objects\":[{\"degree\":[1,1],\"points\":[[0,0,0],[0,0,0],[0,0,0],[0,0,0]]}]}", SF_EINVAL, "/objects"},
        {"{\"camera\":{\"eye\":[1,1,1],\"target\":[1,1,1]},\"objects\":[{\"degree\":[1,1],"
         "\"points\":[[0,0,0],[1,0,0],[0,1,0],[1,1,1]]}]}",
         SF_EINVAL, "/camera/target"},
        {"{\"image\":{\"width\":16384,\"height\":16384},\"objects\":[{\"degree\":[1,1],"
         "\"points\":[[0,0,0],[1,0,0],[0,1,0],[1,1,1]]}]}",
         SF_ELIMIT, "/image"},
    };
    for (size_t k = 0; k < sizeof cases / sizeof *cases; k++) {
        struct scene sc;
        enum image_format img;
        struct sf_err err = {0};
        struct frame *fr = NULL;
        int rc = scene_parse(cases[k].json, strlen(cases[k].json), SCENE_JSON, &sc, &img, &err);
        if (!rc) {
            rc = frame_prepare(&sc, dev, &fr, &err);
            frame_free(fr);
            scene_free(&sc);
        }
        if (rc != cases[k].code || strcmp(err.pointer, cases[k].pointer))
            fprintf(stderr, "  case %zu: rc %d pointer \"%s\" (%s)\n", k, rc, err.pointer, err.message);
        CHECK(rc == cases[k].code);
        CHECK_STR(err.pointer, cases[k].pointer);
    }
}

/* Close up at 120°: the map's outline is widened by the chord error as the projection stretches
 * it toward the frame's corners, and a root that may have a nearer sheet of its patch in front
 * (behind a fold, or seeded by the patch's outline alone) is left to the hierarchy, so auto finds the
 * hierarchy's roots at every pixel; and rays that graze a leaf (where Newton may miss a root or
 * find the farther of two) search its quarters, so the hierarchy matches a dense tessellation. */
TEST(wide_angle_close_up)
{
    struct scene sc;
    if (!load_scene("teapot.json", &sc)) {
        CHECK(!"the teapot scene");
        return;
    }
    const int W = 400, H = 300;
    sc.has_camera = true;
    sc.eye = v3(1.6, -2.2, 2.2), sc.target = v3(0, 0, 1.0), sc.up = v3(0, 0, 1), sc.fov_deg = 120;
    float *mesh = scene_depth(&sc, METHOD_MESH, DENSE_MESH, W, H, false, NULL);
    float *bvh = scene_depth(&sc, METHOD_BVH, DENSE_MESH, W, H, false, NULL);
    float *got = scene_depth(&sc, METHOD_AUTO, DENSE_MESH, W, H, false, NULL);
    CHECK(mesh && bvh && got);
    if (mesh && bvh && got) {
        struct compare c = compare(mesh, bvh, W, H);
        long off = 0; /* every pixel both hit, depth edges or not */
        for (int i = 0; i < W * H; i++)
            off += isfinite(mesh[i]) && isfinite(bvh[i]) && fabsf(bvh[i] - mesh[i]) > 1e-3f * mesh[i];
        fprintf(stderr, "  bvh against the mesh: interior %ld missed %ld extra %ld; %ld depths off\n", c.interior,
                c.missed, c.extra, off);
        CHECK(c.interior > W * H / 10 && c.missed == 0 && c.extra == 0 && off == 0);
        long differ = 0, depth_off = 0;
        for (int i = 0; i < W * H; i++) {
            differ += isfinite(bvh[i]) != isfinite(got[i]);
            depth_off += isfinite(bvh[i]) && isfinite(got[i]) && fabsf(got[i] - bvh[i]) > 1e-4f * bvh[i];
        }
        /* where a patch folds away near a pixel, Newton from the map's seed may settle on the far
         * sheet (17 pixels of this frame did, until roots behind a fold were left to the hierarchy) */
        fprintf(stderr, "  auto against bvh: %ld pixels differ, %ld depths off\n", differ, depth_off);
        CHECK(differ == 0 && depth_off == 0);
    }
    free(mesh);
    free(bvh);
    free(got);
    scene_free(&sc);
}

/* The 8-bit picture a PNG is written from: the table (built from the thresholds between codes)
 * gives round(255 · srgb(c)) at every one of its steps, and a frame that keeps only the picture
 * (its bands in any order) holds the table's code of each pixel of the same frame in float. */
TEST(srgb8_picture)
{
    static struct srgb_table t;
    srgb_table_init(&t);
    long wrong = 0;
    for (int k = 0; k < SRGB_N; k++) {
        double c = (double)k / (SRGB_N - 1), s = c <= 0.0031308 ? 12.92 * c : 1.055 * pow(c, 1 / 2.4) - 0.055;
        wrong += t.code[k] != lround(s * 255);
    }
    CHECK(wrong == 0);
    CHECK(srgb8(&t, -1.0f) == 0 && srgb8(&t, NAN) == 0 && srgb8(&t, 2.0f) == 255 && srgb8(&t, 0.5f) == 188);

    struct scene sc;
    if (!load_scene("teapot.json", &sc)) {
        CHECK(!"the teapot scene");
        return;
    }
    struct sf_err err = {0};
    sc.width = 160, sc.height = 120;
    struct frame *lin, *pic;
    CHECK(frame_prepare(&sc, dev, &lin, &err) == 0);
    sc.srgb8_only = true;
    CHECK(frame_prepare(&sc, dev, &pic, &err) == 0);
    if (!lin || !pic) { /* frame_prepare leaves NULL when it fails */
        frame_free(lin);
        frame_free(pic);
        scene_free(&sc);
        return;
    }
    struct render_stats st = {0};
    frame_band(lin, 0, 120, &st);
    frame_band(pic, 60, 120, &st);
    frame_band(pic, 0, 60, &st);
    struct frame_image a, b;
    frame_image(lin, &a);
    frame_image(pic, &b);
    CHECK(a.rgba && !a.srgb8 && b.srgb8 && !b.rgba && !b.depth);
    long differ = 0, lit = 0;
    const double bg[3] = {sc.background.x, sc.background.y, sc.background.z};
    for (int i = 0; a.rgba && b.srgb8 && i < sc.width * sc.height; i++)
        for (int c = 0; c < 3; c++) { /* the float image is premultiplied: the picture is it over the background */
            float over = (float)(a.rgba[4 * i + c] + (1.0 - a.rgba[4 * i + 3]) * bg[c]);
            differ += b.srgb8[3 * i + c] != srgb8(&t, over);
            lit += a.rgba[4 * i + 3] > 0 && b.srgb8[3 * i + c] > 0;
        }
    CHECK(differ == 0 && lit > 1000);
    frame_free(lin);
    frame_free(pic);
    scene_free(&sc);
}

int main(void)
{
    dev = bvh_device_new(1, NULL);
    RUN(teapot_exact_methods_against_dense_mesh);
    RUN(contour_model_exact);
    RUN(heart_model_auto_equals_bvh);
    RUN(trimmed_mug_auto_equals_bvh);
    RUN(shared_scenes_agree_across_methods);
    RUN(wide_angle_close_up);
    RUN(srgb8_picture);
    RUN(bad_scenes_fail_with_pointer);
    bvh_device_free(dev);
    UNIT_END();
}
