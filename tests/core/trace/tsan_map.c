/* tsan_map.c - the preliminary-value map's steps on several threads at once under the thread
 * sanitizer, as the daemon's workers make a view's map (map_part: the parts of a step on any
 * threads, each step after the one before): a wavy sheet of patches joined by seams, each part's
 * step 1 reading its neighbours' border segments across parts. The tile lists equal those one
 * thread makes (map_build). Linked without the hierarchy: bvh_seam is this file's table. */
#include "../../../core/trace/bvh.h" /* bvh_seam, defined here */
#include "../../../core/trace/map.h"
#include "../../unit.h"

#include <pthread.h>
#include <stdatomic.h>
#include <stdbool.h>

#define NU 32 /* patches along x and y: a sheet of NU x NU bicubics */
#define THREADS 4

static double cw[NU * NU][16][4];
static struct patch ps[NU * NU];

/* The sheet's patch (i, j): z = a wave over x, y; patch (i, j)'s edge u = 1 is (i + 1, j)'s u = 0,
 * its v = 1 is (i, j + 1)'s v = 0. */
int bvh_seam(const struct bvh *b, int patch, int edge)
{
    (void)b;
    int i = patch / NU, j = patch % NU;
    int di = edge == 0 ? -1 : edge == 1 ? 1 : 0, dj = edge == 2 ? -1 : edge == 3 ? 1 : 0;
    return i + di < 0 || i + di >= NU || j + dj < 0 || j + dj >= NU ? -1 : (i + di) * NU + j + dj;
}

struct step {
    struct map *m;
    int step;
    atomic_int next;
};

static void *worker(void *arg)
{
    struct step *s = arg;
    for (int p; (p = atomic_fetch_add(&s->next, 1)) < map_parts(s->m);)
        map_part(s->m, s->step, p);
    return NULL;
}

TEST(parts_on_threads_make_the_same_map)
{
    for (int i = 0; i < NU; i++)
        for (int j = 0; j < NU; j++) {
            struct patch *pt = &ps[i * NU + j];
            for (int a = 0; a < 4; a++)
                for (int b = 0; b < 4; b++) { /* control points of a smooth wave: shared along seams */
                    double x = i + a / 3.0, y = j + b / 3.0;
                    double *c = cw[i * NU + j][a * 4 + b];
                    c[0] = x, c[1] = y, c[2] = 1.2 * sin(1.9 * x) * cos(1.3 * y), c[3] = 1.0;
                }
            *pt = (struct patch){.p = 3, .q = 3, .cw = cw[i * NU + j], .u1 = 1, .v1 = 1};
            bezier_second_bounds(pt);
        }
    struct camera cam;
    camera_init(&cam, v3(NU / 2.0, -6.0, 14.0), v3(NU / 2.0, NU / 2.0, 0.0), v3(0, 0, 1), 70, 1600, 1200);
    const struct bvh *seams = (const struct bvh *)ps; /* any non-NULL pointer: bvh_seam is the table above */
    struct sf_err err = {0};
    struct map *alone = NULL, *shared = NULL;
    REQUIRE(map_build(ps, NU * NU, seams, &cam, &alone, &err) == 0);
    REQUIRE(map_begin(ps, NU * NU, seams, &cam, &shared, &err) == 0);
    fprintf(stderr, "  %d parts, %zu primitive slots\n", map_parts(shared), shared->n_tris);
    CHECK(map_parts(shared) >= THREADS);
    for (int step = 0; step < MAP_STEPS; step++) {
        struct step s = {shared, step, 0};
        pthread_t tid[THREADS];
        for (int k = 0; k < THREADS; k++)
            pthread_create(&tid[k], NULL, worker, &s);
        for (int k = 0; k < THREADS; k++)
            pthread_join(tid[k], NULL);
    }
    REQUIRE(map_end(shared, &err) == 0);
    long listed = 0, seamed = 0;
    for (int y = 0; y < alone->n_tiles; y++) {
        CHECK(alone->tile_n[y] == shared->tile_n[y]);
        for (unsigned k = 0; k < alone->tile_n[y] && k < shared->tile_n[y]; k++)
            CHECK(alone->tile_list[y][k] == shared->tile_list[y][k]);
        listed += alone->tile_n[y];
    }
    for (int k = 0; k < NU * NU; k++)
        seamed += shared->seamed[k];
    fprintf(stderr, "  %ld primitives listed, %ld of %d patches seamed\n", listed, seamed, NU * NU);
    CHECK(listed > 0 && seamed > NU * NU / 2);
    map_free(alone);
    map_free(shared);
}

int main(void)
{
    RUN(parts_on_threads_make_the_same_map);
    UNIT_END();
}
