/* camera.h - the camera of API.md §Scene, shared by the tracer and the map raster: a pinhole, or
 * an orthographic view (parallel rays along f from the eye's plane, hw x hh the half extents:
 * the axis-aligned views a matrix model is made from, seed 003). */
#ifndef SURFD_CAMERA_H
#define SURFD_CAMERA_H

#include <stdbool.h>

#include "../base/vec.h"

struct camera {
    vec3 eye;
    vec3 f, r, u;    /* forward, right, up: orthonormal, u = r × f */
    double th;       /* tan(fov/2), fov vertical */
    double aspect;   /* W / H */
    int W, H;
    bool ortho;      /* orthographic: th unused */
    double hw, hh;   /* orthographic half width and height (world units) */
};

/* f = normalize(target - eye), r = normalize(f × up), u = r × f. */
static inline void camera_init(struct camera *c, vec3 eye, vec3 target, vec3 up, double fov_deg, int W, int H)
{
    c->eye = eye;
    c->f = v3_norm(v3_sub(target, eye));
    c->r = v3_norm(v3_cross(c->f, up));
    c->u = v3_cross(c->r, c->f);
    c->th = tan(fov_deg * M_PI / 360.0);
    c->W = W;
    c->H = H;
    c->aspect = (double)W / H;
    c->ortho = false;
    c->hw = c->hh = 0.0;
}

/* Makes c orthographic with a view of height view_h; view_w <= 0: view_h times the aspect. */
static inline void camera_make_ortho(struct camera *c, double view_h, double view_w)
{
    c->ortho = true;
    c->hh = 0.5 * view_h;
    c->hw = view_w > 0.0 ? 0.5 * view_w : c->hh * c->aspect;
}

/* The ray through point (fx, fy) of the image plane in pixels (pixel (px, py) spans [px, px + 1)
 * x [py, py + 1), py = 0 the top row): its origin into *o, its direction (not normalised for a
 * pinhole) returned. */
static inline vec3 camera_ray_at(const struct camera *c, double fx, double fy, vec3 *o)
{
    double sx = fx / c->W * 2.0 - 1.0, sy = 1.0 - fy / c->H * 2.0;
    if (c->ortho) {
        *o = v3_add(c->eye, v3_add(v3_scale(c->r, sx * c->hw), v3_scale(c->u, sy * c->hh)));
        return c->f;
    }
    *o = c->eye;
    return v3_add(c->f, v3_add(v3_scale(c->r, sx * c->th * c->aspect), v3_scale(c->u, sy * c->th)));
}

/* The ray through the centre of pixel (px, py). */
static inline vec3 camera_ray(const struct camera *c, int px, int py, vec3 *o)
{
    return camera_ray_at(c, px + 0.5, py + 0.5, o);
}

#endif
