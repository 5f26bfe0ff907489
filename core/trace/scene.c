/* scene.c - defaults, ownership and whole-scene validation of struct scene. */
#include "scene.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const char *const METHOD_NAMES[] = {"auto", "map", "bvh", "mesh", "montecarlo"};

void scene_init(struct scene *sc)
{
    memset(sc, 0, sizeof *sc);
    sc->width = 800;
    sc->height = 600;
    sc->background = v3(1, 1, 1);
    sc->samples = 1;
    sc->up = v3(0, 0, 1);
    sc->fov_deg = 35.0;
    sc->azimuth_deg = 30.0;
    sc->elevation_deg = 25.0;
    sc->method = METHOD_AUTO;
    sc->tolerance = 1e-7;
    sc->mesh_tolerance = 1e-4;
    sc->shadows = true;
}

void scene_free(struct scene *sc)
{
    if (!sc)
        return;
    for (int k = 0; !sc->borrowed && k < sc->n_objects; k++) {
        nurbs_surface_free(&sc->objects[k].surf);
        trim_free(sc->objects[k].trim);
        free(sc->objects[k].trim);
    }
    if (!sc->borrowed)
        free(sc->objects);
    free(sc->lights);
    for (int k = 0; !sc->borrowed && k < sc->n_meshes; k++)
        trimesh_free(&sc->meshes[k].m);
    if (!sc->borrowed)
        free(sc->meshes);
    sc->objects = NULL;
    sc->lights = NULL;
    sc->meshes = NULL;
    sc->n_objects = sc->n_lights = sc->cap_objects = sc->n_meshes = 0;
}

struct scene_mesh *scene_add_mesh(struct scene *sc)
{
    if (sc->n_meshes >= SCENE_MAX_OBJECTS)
        return NULL;
    struct scene_mesh *more = realloc(sc->meshes, sizeof *more * (size_t)(sc->n_meshes + 1));
    if (!more)
        return NULL;
    sc->meshes = more;
    struct scene_mesh *m = &sc->meshes[sc->n_meshes++];
    memset(m, 0, sizeof *m);
    m->mat = scene_default_material();
    return m;
}

struct object *scene_add_object(struct scene *sc)
{
    if (sc->n_objects >= SCENE_MAX_OBJECTS)
        return NULL;
    if (sc->n_objects == sc->cap_objects) { /* doubling: a scene of 77 k patches once took 8 s to grow */
        int cap = sc->cap_objects ? 2 * sc->cap_objects : 16;
        cap = cap < SCENE_MAX_OBJECTS ? cap : SCENE_MAX_OBJECTS;
        struct object *more = realloc(sc->objects, sizeof *more * (size_t)cap);
        if (!more)
            return NULL;
        sc->objects = more;
        sc->cap_objects = cap;
    }
    struct object *o = &sc->objects[sc->n_objects++];
    memset(o, 0, sizeof *o);
    o->mat = scene_default_material();
    return o;
}

struct material scene_default_material(void)
{
    return (struct material){v3(0.8, 0.8, 0.8), 0.3, 40.0};
}

static bool finite3(vec3 a) { return isfinite(a.x) && isfinite(a.y) && isfinite(a.z); }

/* Finite and within the coordinate range of control points (nurbs.h). */
static bool in_range3(vec3 a)
{
    return fabs(a.x) <= SURF_MAX_COORD && fabs(a.y) <= SURF_MAX_COORD && fabs(a.z) <= SURF_MAX_COORD;
}

int scene_validate(const struct scene *sc, struct sf_err *err)
{
    if (sc->width < 1 || sc->height < 1 || sc->width > SCENE_MAX_SIDE || sc->height > SCENE_MAX_SIDE)
        return sf_fail(err, SF_EINVAL, sc->width < 1 || sc->width > SCENE_MAX_SIDE ? "/image/width" : "/image/height",
                       "image sides must be 1..%d pixels, not %d x %d", SCENE_MAX_SIDE, sc->width, sc->height);
    if ((unsigned long long)sc->width * (unsigned long long)sc->height > SCENE_MAX_PIXELS)
        return sf_fail(err, SF_ELIMIT, "/image", "image of %d x %d pixels is larger than the limit of %u pixels",
                       sc->width, sc->height, SCENE_MAX_PIXELS);
    if (sc->has_camera) {
        if (!in_range3(sc->eye) || !in_range3(sc->target) || !in_range3(sc->up))
            return sf_fail(err, SF_EINVAL, !in_range3(sc->eye) ? "/camera/eye" : !in_range3(sc->target) ? "/camera/target" : "/camera/up",
                           "camera vectors must be finite and within ±%g", SURF_MAX_COORD);
        vec3 f = v3_sub(sc->target, sc->eye);
        if (v3_len(f) == 0.0)
            return sf_fail(err, SF_EINVAL, "/camera/target", "camera target equals the eye");
        if (v3_len(v3_cross(f, sc->up)) <= 1e-12 * v3_len(f) * v3_len(sc->up))
            return sf_fail(err, SF_EINVAL, "/camera/up", "camera up is parallel to the view direction or zero");
    }
    if (!(sc->view_height >= 0.0 && sc->view_height <= SURF_MAX_COORD) ||
        !(sc->view_width >= 0.0 && sc->view_width <= SURF_MAX_COORD))
        return sf_fail(err, SF_EINVAL, "/camera/view_height", "view_height must be within (0, %g], not %g",
                       SURF_MAX_COORD, sc->view_height);
    if (sc->view < VIEW_NONE || sc->view > VIEW_NZ)
        return sf_fail(err, SF_EINVAL, "/camera/view", "view is +x, -x, +y, -y, +z or -z");
    if (!(sc->fov_deg > 0.0 && sc->fov_deg < 179.0))
        return sf_fail(err, SF_EINVAL, "/camera/fov_deg", "fov_deg must be in (0, 179), not %g", sc->fov_deg);
    if (!isfinite(sc->azimuth_deg) || !(sc->elevation_deg >= -89.9 && sc->elevation_deg <= 89.9))
        return sf_fail(err, SF_EINVAL, "/camera", "azimuth must be finite and elevation within ±89.9 degrees");
    for (int k = 0; k < sc->n_lights; k++) {
        const struct light *l = &sc->lights[k];
        if (!in_range3(l->v) || !finite3(l->color) || (!l->point && v3_len(l->v) == 0.0))
            return sf_fail(err, SF_EINVAL, "/lights", "light %d needs a finite, non-zero direction and colour", k);
    }
    if (!(sc->tolerance >= 1e-15 && sc->tolerance <= 1e-2))
        return sf_fail(err, SF_EINVAL, "/render/tolerance", "tolerance must be within [1e-15, 1e-2], not %g",
                       sc->tolerance);
    if (!(sc->mesh_tolerance >= 1e-7 && sc->mesh_tolerance <= 1e-1))
        return sf_fail(err, SF_EINVAL, "/render/mesh_tolerance", "mesh_tolerance must be within [1e-7, 0.1], not %g",
                       sc->mesh_tolerance);
    if (sc->samples < 1 || sc->samples > SCENE_MAX_SAMPLES)
        return sf_fail(err, SF_EINVAL, "/image/samples", "samples must be 1..%d rays a pixel, not %d", SCENE_MAX_SAMPLES,
                       sc->samples);
    if (!finite3(sc->background))
        return sf_fail(err, SF_EINVAL, "/image/background", "background must be three finite numbers");
    if (sc->n_objects < 1 && sc->n_meshes < 1)
        return sf_fail(err, SF_EINVAL, "/objects", "a scene needs at least one object");
    if (sc->n_meshes && sc->method != METHOD_AUTO && sc->method != METHOD_BVH)
        return sf_fail(err, SF_EINVAL, "?method", "a scene with a triangle-mesh model (an isosurface) renders with "
                       "method auto or bvh, not %s", scene_method_name(sc->method));
    return 0;
}

const char *scene_method_name(enum render_method m) { return METHOD_NAMES[m]; }

int scene_method_parse(const char *name, enum render_method *m)
{
    for (size_t k = 0; k < sizeof METHOD_NAMES / sizeof *METHOD_NAMES; k++)
        if (!strcmp(name, METHOD_NAMES[k])) {
            *m = (enum render_method)k;
            return 0;
        }
    return SF_EINVAL;
}

int scene_patches(const struct scene *sc, struct patch_set *ps, struct sf_err *err)
{
    char where[32];
    int rc = 0;
    memset(ps, 0, sizeof *ps);
    for (int k = 0; k < sc->n_objects && !rc; k++) {
        snprintf(where, sizeof where, "/objects/%d", k);
        rc = nurbs_validate(&sc->objects[k].surf, where, err);
    }
    for (int k = 0; k < sc->n_objects && !rc; k++)
        if ((rc = nurbs_extract(&sc->objects[k].surf, k, ps)))
            rc = sf_fail(err, rc, "", "out of memory");
    if (rc) {
        nurbs_patch_set_free(ps);
        return rc;
    }
    nurbs_patches_fix(ps);
    size_t kept = 0;
    for (size_t k = 0; k < ps->n; k++) {
        struct patch *pt = &ps->patches[k];
        const struct trim *t = sc->objects[pt->surface].trim;
        enum trim_class c = t ? trim_classify(t, pt->u0, pt->u1, pt->v0, pt->v1) : TRIM_IN;
        if (c == TRIM_OUT)
            continue; /* trimmed away whole */
        pt->trim = c == TRIM_CUT ? t : NULL;
        bezier_second_bounds(pt); /* the tracer's Newton steps stop on them */
        ps->patches[kept++] = *pt;
    }
    ps->n = kept;
    if (kept == 0 && sc->n_objects > 0) { /* every patch trimmed away */
        scene_object_pointer(sc, 0, where, sizeof where);
        nurbs_patch_set_free(ps);
        return sf_fail(err, SF_EINVAL, where, "the trim loops leave nothing of any surface: every loop lies off its "
                       "surface's parameter domain");
    }
    return 0;
}

void scene_object_pointer(const struct scene *sc, int k, char *where, size_t n)
{
    if (k >= 0 && k < sc->n_objects && sc->objects[k].source)
        snprintf(where, n, "D%d", sc->objects[k].source);
    else
        snprintf(where, n, "/objects/%d", k);
}

unsigned scene_aov_parse(const char *name, size_t n)
{
    return n == 6 && !strncmp(name, "normal", 6) ? AOV_NORMAL : n == 2 && !strncmp(name, "uv", 2) ? AOV_UV
                                                              : n == 2 && !strncmp(name, "id", 2) ? AOV_ID
                                                                                                 : 0;
}

int scene_view_parse(const char *name, int *view)
{
    static const char *const NAMES[] = {"+x", "+y", "+z", "-x", "-y", "-z"};
    for (int k = 0; k < 6; k++)
        if (!strcmp(name, NAMES[k]) || !strcmp(name, NAMES[k] + (k < 3))) {
            *view = VIEW_PX + k;
            return 0;
        }
    return -1;
}

void scene_view_axes(int v, vec3 *toward_eye, vec3 *up)
{
    int axis = (v - VIEW_PX) % 3;
    double s = v <= VIEW_PZ ? 1.0 : -1.0;
    *toward_eye = v3(axis == 0 ? s : 0, axis == 1 ? s : 0, axis == 2 ? s : 0);
    *up = axis == 2 ? v3(0, 1, 0) : v3(0, 0, 1); /* rows as matrix.h's Table 1 lays them out */
}
