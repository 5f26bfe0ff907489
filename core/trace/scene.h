/* scene.h - what a render request describes, as plain data: image, camera, lights, render
 * options and the free-form objects. api/ fills it from JSON, .bpt or VRML; core/ reads it.
 * The scene owns its objects and lights; scene_free() releases them. */
#ifndef SURFD_SCENE_H
#define SURFD_SCENE_H

#include <stdbool.h>

#include "../base/err.h"
#include "../geom/nurbs.h"
#include "../geom/trimesh.h"
#include "../base/vec.h"

#define SCENE_MAX_SIDE 16384          /* image width or height */
#define SCENE_MAX_PIXELS (64u << 20)  /* width * height */
#define SCENE_MAX_OBJECTS 100000
#define SCENE_MAX_LIGHTS 64
#define SCENE_MAX_SAMPLES 64          /* rays a pixel */

enum render_method { METHOD_AUTO, METHOD_MAP, METHOD_BVH, METHOD_MESH, METHOD_MONTECARLO };

/* The views along the axes (API.md ?view=+x...), in matrix order: M0 is seen from +x, M1 from
 * +y, M2 from +z, M3 from -x, M4 from -y, M5 from -z (matrix.h's Table 1). */
enum scene_view { VIEW_NONE, VIEW_PX, VIEW_PY, VIEW_PZ, VIEW_NX, VIEW_NY, VIEW_NZ };

enum aov { AOV_NORMAL = 1, AOV_UV = 2, AOV_ID = 4 };

struct material {
    vec3 color;        /* diffuse albedo, linear RGB in [0, 1] */
    double specular;   /* Blinn–Phong specular weight */
    double shininess;  /* Blinn–Phong exponent */
};

struct light {
    bool point;        /* false: directional */
    vec3 v;            /* direction the light travels (directional) or position (point) */
    vec3 color;
    bool no_shadow;    /* casts no shadow rays (the default head light: its shadows hide behind the objects) */
};

struct object {
    struct surface surf;
    struct material mat;
    struct trim *trim; /* owned; NULL: untrimmed (the whole domain) */
    int source;        /* the input's own number for it (an IGES entity's first directory line), 0: none */
    char name[48];     /* the input's name for it (an IGES 406 name, else the entity's label), "" if none */
};

/* A triangle mesh beside the free-form objects (an isosurface model), shaded with its normals. */
struct scene_mesh {
    struct trimesh m;
    struct material mat;
};

struct scene {
    int width, height;
    vec3 background;
    bool background_opaque;   /* the request gave a background: EXR/TIFF pixels composite over it
                               * (alpha 1); else premultiplied, RGB 0 where alpha is 0 */
    int samples;              /* primary rays a pixel (1: its centre; more: stratified over it,
                               * alpha the covered fraction) */
    unsigned aovs;            /* AOV_* bits wanted besides colour and depth */
    bool srgb8_only;          /* keep only the 8-bit sRGB picture (a PNG's pixels, converted band by
                               * band on the render's threads): no float colour, depth or AOVs */
    bool has_camera;          /* false: frame the bounds from azimuth/elevation */
    vec3 eye, target, up;
    double fov_deg;           /* vertical field of view */
    double azimuth_deg, elevation_deg;
    int view;                 /* 0, or looking from the bounds' side VIEW_PX..VIEW_NZ (instead of
                               * azimuth/elevation): the six views of a matrix model (seed 003) */
    bool ortho;               /* orthographic projection */
    double view_height;       /* orthographic view's height (world units); 0: the bounds fit */
    double view_width;        /* its width; 0: the height times the image's aspect */
    struct light *lights;     /* none: a key light and a head light */
    int n_lights;
    enum render_method method;
    double tolerance;         /* root residual, relative to the scene's size */
    double mesh_tolerance;    /* chord error of the mesh method, relative to the scene's size */
    bool shadows;
    struct object *objects;
    int n_objects, cap_objects; /* scene_add_object() grows objects */
    struct scene_mesh *meshes;  /* traced with auto or bvh: the map and the mesh method are the patches' */
    int n_meshes;
    bool borrowed;            /* objects and meshes are another scene's: scene_free leaves them */
};

/* Defaults of API.md: 800x600, white background, auto method, shadows on. */
void scene_init(struct scene *sc);
void scene_free(struct scene *sc);
/* Appends an object and returns it (zeroed, default material), or NULL when out of memory
 * or over SCENE_MAX_OBJECTS. The scene owns what the caller then puts in it. */
struct object *scene_add_object(struct scene *sc);
/* Appends a mesh (empty, default material), or NULL when out of memory or over SCENE_MAX_OBJECTS. */
struct scene_mesh *scene_add_mesh(struct scene *sc);
/* Light grey, a little specular. */
struct material scene_default_material(void);
/* Checks everything but the surfaces' own validity (nurbs_validate does that per object):
 * image size, camera, lights, options, at least one object. */
int scene_validate(const struct scene *sc, struct sf_err *err);
/* Every object as Bézier patches (validated first: errors point at /objects/k), those its trims cut
 * away whole left out (none left: an error); the caller frees ps. */
int scene_patches(const struct scene *sc, struct patch_set *ps, struct sf_err *err);
const char *scene_method_name(enum render_method m);
/* Where object k came from, for an error: its IGES entity ("D5") or "/objects/k". */
void scene_object_pointer(const struct scene *sc, int k, char *where, size_t n);
/* The AOV_* bit of the n characters at name ("normal", "uv", "id"), or 0. */
unsigned scene_aov_parse(const char *name, size_t n);
/* "+x", "-x", ... (also "x" for +x) to VIEW_*; 0, or -1 for another name. */
int scene_view_parse(const char *name, int *view);
/* The unit direction from the bounds toward the eye of view v, and the view's up. */
void scene_view_axes(int v, vec3 *toward_eye, vec3 *up);
int scene_method_parse(const char *name, enum render_method *m);

#endif
