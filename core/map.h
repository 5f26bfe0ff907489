/* map.h - the preliminary-value map of seed 000 (eq. 5–6, Table 1), made exact-safe: per pixel
 * the nearest patch id with float (u, v) and depth, plus the nearest fragment of a *different*
 * patch, rasterised conservatively from a tessellation whose chord error is under half a pixel.
 * So every pixel the true surface covers has a candidate, and pixels where two patches lie
 * within the tessellation error of each other get both tried. Caller frees with map_free(). */
#ifndef SURFD_MAP_H
#define SURFD_MAP_H

#include <stdbool.h>
#include <stddef.h>

#include "bezier.h"
#include "camera.h"
#include "err.h"

struct map_cand {
    int patch;    /* -1: none */
    float u, v;   /* seed in patch parameters */
    float z;      /* camera depth of the seed */
};

struct map {
    int W, H;
    struct map_cand *near;   /* W*H: nearest fragment */
    struct map_cand *other;  /* W*H: nearest fragment of another patch */
    float *slack;            /* W*H: depth within which `other` is a contender */
    bool complete;           /* false: some patch crosses the eye plane; trust no pixel */
    size_t n_tris;
};

int map_build(const struct patch *patches, size_t n, const struct camera *cam, struct map **out, struct sf_err *err);
void map_free(struct map *m);

#endif
