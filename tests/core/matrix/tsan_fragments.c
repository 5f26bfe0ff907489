/* tsan_fragments.c - matrix_fragments on several threads at once under the thread sanitizer: the
 * fragment table is made once a process by whichever call comes first and published through an
 * atomic pointer (core/matrix/fragment.c), as a daemon's workers mesh matrix models side by side.
 * Every thread's mesh equals the one made alone. */
#include "../../../core/matrix/matrix.h"
#include "../../unit.h"

#include <pthread.h>
#include <stdbool.h>
#include <stdlib.h>
#include <string.h>

#define N 24
#define THREADS 4

static uint8_t vox[N * N * N];

static void *mesh_on_thread(void *arg)
{
    int n[3] = {N, N, N};
    struct matrix_stats st;
    struct sf_err err = {0};
    if (matrix_fragments(n, vox, (double[3]){0, 0, 0}, (double[3]){1, 1, 1}, arg, &st, &err))
        *(struct trimesh *)arg = (struct trimesh){0};
    return NULL;
}

static bool same_mesh(const struct trimesh *a, const struct trimesh *b)
{
    return a->n_vert == b->n_vert && a->n_tri == b->n_tri && !memcmp(a->pos, b->pos, sizeof *a->pos * 3 * a->n_vert) &&
           !memcmp(a->tri, b->tri, sizeof *a->tri * 3 * a->n_tri);
}

TEST(threads_share_the_fragment_table)
{
    for (int z = 0; z < N; z++) /* a ball with a box beside it */
        for (int y = 0; y < N; y++)
            for (int x = 0; x < N; x++) {
                double a = x - 8.5, b = y - 11.5, c = z - 11.5;
                vox[x + N * (y + N * z)] = a * a + b * b + c * c < 49 || (x >= 17 && x < 22 && y >= 4 && y < 20 && z >= 6 && z < 12);
            }
    /* the threads' first calls race to make the table; the mesh made alone comes after */
    pthread_t t[THREADS];
    struct trimesh m[THREADS], alone;
    for (int i = 0; i < THREADS; i++)
        CHECK(pthread_create(&t[i], NULL, mesh_on_thread, &m[i]) == 0);
    for (int i = 0; i < THREADS; i++)
        pthread_join(t[i], NULL);
    int n[3] = {N, N, N};
    struct matrix_stats st;
    struct sf_err err = {0};
    CHECK(matrix_fragments(n, vox, (double[3]){0, 0, 0}, (double[3]){1, 1, 1}, &alone, &st, &err) == 0);
    CHECK(alone.n_tri > 0);
    for (int i = 0; i < THREADS; i++) {
        CHECK(same_mesh(&m[i], &alone));
        trimesh_free(&m[i]);
    }
    trimesh_free(&alone);
}

int main(void)
{
    RUN(threads_share_the_fragment_table);
    UNIT_END();
}
