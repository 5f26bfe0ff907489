/* camera.h - the pinhole camera of API.md §Scene, shared by the tracer and the map raster. */
#ifndef SURFD_CAMERA_H
#define SURFD_CAMERA_H

#include "../base/vec.h"

struct camera {
    vec3 eye;
    vec3 f, r, u;    /* forward, right, up: orthonormal, u = r × f */
    double th;       /* tan(fov/2), fov vertical */
    double aspect;   /* W / H */
    int W, H;
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
}

/* Direction (not normalised) through pixel (px, py), py = 0 the top row. */
static inline vec3 camera_dir(const struct camera *c, int px, int py)
{
    double sx = ((px + 0.5) / c->W * 2.0 - 1.0) * c->th * c->aspect;
    double sy = (1.0 - (py + 0.5) / c->H * 2.0) * c->th;
    return v3_add(c->f, v3_add(v3_scale(c->r, sx), v3_scale(c->u, sy)));
}

#endif
