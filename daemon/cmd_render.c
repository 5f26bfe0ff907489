/* cmd_render.c - `surfd render SCENE... -o OUT`: the offline renderer. Reads the scene (JSON,
 * .bpt or VRML NurbsSurface; several text files are one scene), prepares one frame (its map's
 * parts tessellated by --threads threads) and lets them claim its scanline bands, then writes PNG/EXR/TIFF by the output's
 * extension. --stats prints one JSON line on stderr. */
#include <errno.h>
#include <stdbool.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "../core/base/clock.h"
#include "../api/image.h"
#include "../api/png.h"
#include "../api/render_request.h"
#include "../api/scene_io.h"
#include "../core/trace/render.h"
#include "cli.h"

#define BAND_ROWS 16 /* rows per band: one map tile (MAP_TILE_ROWS); 64 bands balance two cores at 1024 rows */

/* What the threads share out, item by item: the map's parts, the frame's bands or the PNG's. */
struct band_work {
    enum { PARTS, BANDS, DEFLATE } what;
    int n, step;
    struct frame *fr;
    int height;
    struct png_bands *png;
    atomic_int next;
    pthread_mutex_t lock;
    struct render_stats total;
};

static void *band_worker(void *arg)
{
    struct band_work *w = arg;
    struct render_stats st = {0};
    for (int k; (k = atomic_fetch_add(&w->next, 1)) < w->n;) {
        if (w->what == PARTS)
            frame_part(w->fr, w->step, k);
        else if (w->what == DEFLATE)
            png_band(w->png, k);
        else
            frame_band(w->fr, k * BAND_ROWS, (k + 1) * BAND_ROWS < w->height ? (k + 1) * BAND_ROWS : w->height, &st);
    }
    pthread_mutex_lock(&w->lock);
    render_stats_add(&w->total, &st);
    pthread_mutex_unlock(&w->lock);
    return NULL;
}

/* w's items on n_threads threads (this one among them). */
static void share_out(struct band_work *w, int n_threads)
{
    pthread_t tid[256];
    atomic_init(&w->next, 0);
    for (int k = 1; k < n_threads && k < w->n; k++)
        pthread_create(&tid[k], NULL, band_worker, w);
    band_worker(w);
    for (int k = 1; k < n_threads && k < w->n; k++)
        pthread_join(tid[k], NULL);
}

static bool camera_flag(const char *name, const char *const *flags, int n)
{
    for (int k = 0; k < n; k++)
        if (!strcmp(name, flags[k]))
            return true;
    return false;
}

void cmd_render_usage(FILE *f)
{
    fprintf(f, "usage: surfd render SCENE... -o OUT.png|OUT.exr|OUT.tif [--method auto|map|bvh|mesh|montecarlo]\n"
                    "                    [--width W --height H] [--threads N] [--format json|bpt|nurbs|iges] [--stats]\n"
                    "                    [--azimuth DEG --elevation DEG] [--no-shadows] [--aovs normal,uv,id]\n"
                    "                    [--eye X,Y,Z --target X,Y,Z] [--up X,Y,Z] [--fov DEG]\n"
                    "                    [--projection perspective|orthographic] [--view +x|-x|+y|-y|+z|-z] [--view-height H]\n"
                    "                    [--samples N] (rays a pixel, 1..64: anti-aliased, alpha fractional at silhouettes)\n");
    }

static int usage(void)
{
    cmd_render_usage(stderr);
    return 2;
}

/* Reads and concatenates the input files (capped at SCENE_MAX_BODY). */
static char *read_inputs(char **paths, int n, size_t *len)
{
    size_t cap = 0, used = 0;
    char *buf = NULL;
    for (int k = 0; k < n; k++) {
        FILE *f = fopen(paths[k], "rb");
        if (!f) {
            fprintf(stderr, "surfd: %s: %s\n", paths[k], strerror(errno));
            free(buf);
            return NULL;
        }
        char chunk[65536];
        size_t got;
        while ((got = fread(chunk, 1, sizeof chunk, f)) > 0) {
            if (used + got + 2 > SCENE_MAX_BODY) {
                fprintf(stderr, "surfd: input over %u bytes\n", SCENE_MAX_BODY);
                fclose(f);
                free(buf);
                return NULL;
            }
            if (used + got + 2 > cap) {
                cap = (used + got + 2) * 2;
                char *nb = realloc(buf, cap);
                if (!nb) {
                    fclose(f);
                    free(buf);
                    return NULL;
                }
                buf = nb;
            }
            memcpy(buf + used, chunk, got);
            used += got;
        }
        fclose(f);
        if (buf)
            buf[used++] = '\n';
    }
    if (buf)
        buf[used] = 0;
    *len = used;
    return buf;
}

static enum scene_format format_of(const char *path)
{
    const char *dot = strrchr(path, '.');
    return dot ? scene_format_parse(dot + 1) : SCENE_UNKNOWN;
}

/* What the command line asks for. */
struct render_args {
    const char *out, *method, *fmt_name, *aovs;
    int width, height, threads, stats, no_shadows;
    double az, el;
    char *inputs[64];
    int n_inputs;
    char camera[1024];       /* the camera flags as POST /render's query */
};

/* argv into a: 0, or usage()'s 2. */
static int parse_args(int argc, char **argv, struct render_args *a)
{
    static const char *const CAMERA_FLAGS[] = {"eye", "target", "up", "fov", "projection", "view", "view-height", "samples"};
    *a = (struct render_args){.threads = (int)sysconf(_SC_NPROCESSORS_ONLN), .az = NAN, .el = NAN};
    for (int k = 1; k < argc; k++) {
        const char *f = argv[k];
        const char *val = k + 1 < argc ? argv[k + 1] : NULL;
        if (!strcmp(f, "-o") && val)
            a->out = val, k++;
        else if (!strcmp(f, "--method") && val)
            a->method = val, k++;
        else if (!strcmp(f, "--format") && val)
            a->fmt_name = val, k++;
        else if (!strcmp(f, "--aovs") && val)
            a->aovs = val, k++;
        else if (!strcmp(f, "--width") && val)
            a->width = atoi(val), k++;
        else if (!strcmp(f, "--height") && val)
            a->height = atoi(val), k++;
        else if (!strcmp(f, "--threads") && val)
            a->threads = atoi(val), k++;
        else if (!strcmp(f, "--azimuth") && val)
            a->az = atof(val), k++;
        else if (!strcmp(f, "--elevation") && val)
            a->el = atof(val), k++;
        else if (!strcmp(f, "--stats"))
            a->stats = 1;
        else if (f[0] == '-' && f[1] == '-' && val && camera_flag(f + 2, CAMERA_FLAGS, 8)) {
            size_t at = strlen(a->camera);
            snprintf(a->camera + at, sizeof a->camera - at, "%s%s=%s", at ? "&" : "", f + 2, val);
            for (char *c = a->camera + at; *c != '='; c++)
                *c = *c == '-' ? '_' : *c;
            k++;
        }
        else if (!strcmp(f, "--no-shadows"))
            a->no_shadows = 1;
        else if (f[0] == '-' && f[1])
            return usage();
        else if (a->n_inputs < 64)
            a->inputs[a->n_inputs++] = argv[k];
    }
    return !a->out || a->n_inputs == 0 || a->threads < 1 ? usage() : 0;
}

/* The inputs read into sc with the flags applied: 0, or the command's exit code (said on stderr). */
static int scene_of_args(struct render_args *a, enum image_format img_fmt, struct scene *sc)
{
    enum scene_format sfmt = a->fmt_name ? scene_format_parse(a->fmt_name) : format_of(a->inputs[0]);
    size_t len = 0;
    char *buf = read_inputs(a->inputs, a->n_inputs, &len);
    if (!buf)
        return 1;
    struct sf_err err = {0};
    enum image_format ignored;
    int rc = scene_parse(buf, len, sfmt, sc, &ignored, &err);
    free(buf);
    if (rc) {
        fprintf(stderr, "surfd: %s: %s%s%s\n", a->inputs[0], err.message, err.pointer[0] ? " at " : "", err.pointer);
        return 1;
    }
    if (a->method && scene_method_parse(a->method, &sc->method)) {
        fprintf(stderr, "surfd: unknown method \"%s\"\n", a->method);
        scene_free(sc);
        return 2;
    }
    if (a->width > 0)
        sc->width = a->width;
    if (a->height > 0)
        sc->height = a->height;
    if (a->az == a->az)
        sc->azimuth_deg = a->az;
    if (a->el == a->el)
        sc->elevation_deg = a->el;
    if (a->no_shadows)
        sc->shadows = false;
    if (render_options_apply(a->camera, sc, &ignored, &err)) { /* a bad flag; frame_prepare checks the rest */
        fprintf(stderr, "surfd: %s%s%s\n", err.message, err.pointer[0] ? " at " : "", err.pointer);
        scene_free(sc);
        return 2;
    }
    if (img_fmt == IMG_PNG)
        sc->srgb8_only = true; /* the bands convert to 8 bits, on every thread */
    if (a->aovs) {
        sc->aovs |= strstr(a->aovs, "normal") ? AOV_NORMAL : 0;
        sc->aovs |= strstr(a->aovs, "uv") ? AOV_UV : 0;
        sc->aovs |= strstr(a->aovs, "id") ? AOV_ID : 0;
    }
    return 0;
}

int cmd_render(int argc, char **argv)
{
    struct render_args a;
    int rc = parse_args(argc, argv, &a);
    if (rc)
        return rc;
    const char *out = a.out;
    int threads = a.threads, stats = a.stats;
    enum image_format img_fmt = IMG_PNG;
    const char *odot = strrchr(out, '.');
    if (!odot || image_format_parse(odot + 1, &img_fmt)) {
        fprintf(stderr, "surfd: the output's extension must be .png, .exr or .tif\n");
        return 2;
    }
    struct scene sc;
    struct sf_err err = {0};
    if ((rc = scene_of_args(&a, img_fmt, &sc)))
        return rc;

    struct bvh_device *dev = bvh_device_new(threads, &err);
    struct frame *fr = NULL;
    int n_threads = threads > 256 ? 256 : threads;
    if (dev && (rc = frame_begin(&sc, dev, &fr, &err)) == 0) {
        struct band_work parts = {.what = PARTS, .n = frame_parts(fr), .fr = fr, .lock = PTHREAD_MUTEX_INITIALIZER};
        for (; parts.step < frame_steps(fr); parts.step++)
            share_out(&parts, n_threads);
        if ((rc = frame_end(fr, &err)))
            frame_free(fr);
    }
    if (!dev || rc) {
        fprintf(stderr, "surfd: %s%s%s\n", err.message, err.pointer[0] ? " at " : "", err.pointer);
        bvh_device_free(dev);
        scene_free(&sc);
        return 1;
    }
    double i0 = sf_now_ms();
    if (img_fmt != IMG_PNG && image_init(&err)) { /* a daemon pays this once: keep it out of encode_ms */
        fprintf(stderr, "surfd: %s\n", err.message);
        frame_free(fr);
        bvh_device_free(dev);
        scene_free(&sc);
        return 1;
    }
    double init_ms = sf_now_ms() - i0;
    struct band_work w = {.what = BANDS, .n = (sc.height + BAND_ROWS - 1) / BAND_ROWS, .fr = fr, .height = sc.height,
                          .lock = PTHREAD_MUTEX_INITIALIZER};
    double t0 = sf_now_ms();
    share_out(&w, n_threads);
    double render_ms = sf_now_ms() - t0;

    struct frame_image img;
    frame_image(fr, &img);
    unsigned char *bytes = NULL;
    size_t n_bytes = 0;
    double e0 = sf_now_ms();
    struct band_work deflate = {.what = DEFLATE, .png = img_fmt == IMG_PNG ? png_bands_new(img.srgb8, img.width, img.height, png_band_rows(img.width)) : NULL};
    if (deflate.png) { /* the PNG deflated by bands on the threads (png.h) */
        deflate.n = png_bands_n(deflate.png);
        share_out(&deflate, n_threads);
        rc = png_join(deflate.png, &bytes, &n_bytes, &err);
        png_bands_free(deflate.png);
    } else {
        rc = image_encode(&img, img_fmt, &bytes, &n_bytes, &err);
    }
    double encode_ms = sf_now_ms() - e0;
    if (!rc) {
        FILE *f = fopen(out, "wb");
        if (!f || fwrite(bytes, 1, n_bytes, f) != n_bytes) {
            fprintf(stderr, "surfd: %s: %s\n", out, strerror(errno));
            rc = 1;
        }
        if (f && fclose(f))
            rc = 1;
    } else {
        fprintf(stderr, "surfd: %s\n", err.message);
    }
    if (stats && !rc) {
        const struct render_stats *s = &w.total;
        fprintf(stderr,
                "{\"method\":\"%s\",\"width\":%d,\"height\":%d,\"threads\":%d,\"patches\":%zu,"
                "\"image_init_ms\":%.3f,\"prepare_ms\":%.3f,\"render_ms\":%.3f,\"encode_ms\":%.3f,\"bytes\":%zu,\"rays\":%ld,"
                "\"primary\":%ld,\"hits\":%ld,\"misses\":%ld,\"fallback_hits\":%ld,\"refinements\":%ld,"
                "\"iterations\":%ld,\"iterations_mean\":%.3f,\"shadow_rays\":%ld,\"shadow_iterations\":%ld}\n",
                scene_method_name(sc.method), sc.width, sc.height, n_threads, frame_n_patches(fr), init_ms,
                frame_prepare_ms(fr), render_ms, encode_ms, n_bytes, s->rays, s->primary, s->hits, s->misses,
                s->fallback_hits, s->refinements, s->iterations,
                s->iterations / (double)(s->primary ? s->primary : 1), s->shadow, s->shadow_iterations);
    }
    free(bytes);
    frame_free(fr);
    bvh_device_free(dev);
    scene_free(&sc);
    return rc ? 1 : 0;
}
