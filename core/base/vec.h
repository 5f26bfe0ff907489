/* vec.h - plain 3-vectors for the hot numeric paths; header-only, no allocation. */
#ifndef SURFD_VEC_H
#define SURFD_VEC_H

#include <math.h>

typedef struct { double x, y, z; } vec3;

static inline vec3 v3(double x, double y, double z) { return (vec3){x, y, z}; }
static inline vec3 v3_add(vec3 a, vec3 b) { return v3(a.x + b.x, a.y + b.y, a.z + b.z); }
static inline vec3 v3_sub(vec3 a, vec3 b) { return v3(a.x - b.x, a.y - b.y, a.z - b.z); }
static inline vec3 v3_scale(vec3 a, double s) { return v3(a.x * s, a.y * s, a.z * s); }
static inline vec3 v3_mad(vec3 a, vec3 b, double s) { return v3(a.x + b.x * s, a.y + b.y * s, a.z + b.z * s); }
static inline double v3_dot(vec3 a, vec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
/* The same of two 3-vectors kept as arrays. */
static inline double dot3(const double a[3], const double b[3]) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
static inline vec3 v3_cross(vec3 a, vec3 b)
{
    return v3(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x);
}
static inline double v3_len(vec3 a) { return sqrt(v3_dot(a, a)); }
static inline vec3 v3_norm(vec3 a)
{
    double l = v3_len(a);
    return l > 0 ? v3_scale(a, 1.0 / l) : a;
}
/* The distance from p to segment a-b; *t (may be NULL) gets where along it (0..1) the nearest point lies. */
static inline double v3_seg_dist(vec3 a, vec3 b, vec3 p, double *t)
{
    vec3 d = v3_sub(b, a);
    double dd = v3_dot(d, d), f = dd > 0 ? v3_dot(v3_sub(p, a), d) / dd : 0.0;
    f = f < 0 ? 0 : f > 1 ? 1 : f;
    if (t)
        *t = f;
    return v3_len(v3_sub(p, v3_mad(a, d, f)));
}
/* Minimum and maximum by one comparison: inlined, where fmin/fmax are libm calls (they must
 * treat NaN specially); with a NaN these return b. */
static inline double dmin(double a, double b) { return a < b ? a : b; }
static inline double dmax(double a, double b) { return a > b ? a : b; }
static inline vec3 v3_min(vec3 a, vec3 b) { return v3(dmin(a.x, b.x), dmin(a.y, b.y), dmin(a.z, b.z)); }
static inline vec3 v3_max(vec3 a, vec3 b) { return v3(dmax(a.x, b.x), dmax(a.y, b.y), dmax(a.z, b.z)); }
static inline vec3 v3_mul(vec3 a, vec3 b) { return v3(a.x * b.x, a.y * b.y, a.z * b.z); }

#endif
