/* cmd_iso.c - `surfd isosurface FILE`: a volume (raw with --dims/--type, NRRD, MetaImage, their
 * detached headers with the data file beside them) to the same mesh and figures POST /isosurface
 * makes, offline (a label map's --label N and --labels all too: {"models": [...]}, -o OUT.stl
 * writing OUT-N.stl for label N); --threads N runs the slabs of each pass on N threads as the daemon's pool does;
 * -o OUT.stl|.ply|.obj writes the mesh; --stats adds the extraction's timings at every thread
 * count asked, for the benchmarks. */
#include <dirent.h>
#include <malloc.h>
#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "../core/base/clock.h"
#include "../api/iso_json.h"
#include "../api/matrix_json.h"
#include "../api/mesh_io.h"
#include "../api/volume_io.h"
#include "../core/iso/kept.h"
#include "../core/iso/labels.h"
#include "cli.h"

/* fn(ctx, k) for k in [0, n) on `threads` threads, each taking the next k. */
struct pass {
    void (*fn)(void *ctx, int k);
    void *ctx;
    int n;
    atomic_int next;
};

static void *worker(void *arg)
{
    struct pass *p = arg;
    for (int k; (k = atomic_fetch_add(&p->next, 1)) < p->n;)
        p->fn(p->ctx, k);
    return NULL;
}

static void parallel(int n, int threads, void (*fn)(void *ctx, int k), void *ctx)
{
    struct pass p = {fn, ctx, n, 0};
    pthread_t t[64];
    int started = 0;
    for (int k = 1; k < threads && k < 64; k++)
        started += pthread_create(&t[started], NULL, worker, &p) == 0;
    worker(&p);
    for (int k = 0; k < started; k++)
        pthread_join(t[k], NULL);
}

static void count_slab(void *j, int s) { iso_count(j, s); }
static void emit_slab(void *j, int s) { iso_emit(j, s); }

struct adapt_phase {
    struct iso_adapt *a;
    int phase;
};

static void adapt_slab(void *ctx, int s)
{
    struct adapt_phase *p = ctx;
    iso_adapt_run(p->a, p->phase, s);
}

static int extract(const struct volume *v, int threads, struct trimesh *m, struct iso_adapt_stats *as, double *ms,
                   struct sf_err *err)
{
    double t0 = sf_now_ms();
    struct iso_opts o = volume_iso_opts(v);
    if (volume_adaptive(v)) { /* the adaptive hierarchy: its phases' slabs on the threads */
        struct iso_adapt *a;
        int rc = iso_adapt_begin(&v->g, &o, v->levels, v->max_error, &a, err);
        if (rc)
            return rc;
        for (int p = 0; p < iso_adapt_phases(a); p++) {
            struct adapt_phase ph = {a, p};
            parallel(iso_adapt_n_slabs(a), threads, adapt_slab, &ph);
            iso_adapt_between(a, p);
        }
        rc = iso_adapt_end(a, m, as, err);
        *ms = sf_now_ms() - t0;
        return rc;
    }
    struct iso_job *j;
    int rc = iso_begin(&v->g, &o, threads * 4, &j, err);
    if (rc)
        return rc;
    parallel(iso_n_slabs(j), threads, count_slab, j);
    if ((rc = iso_layout(j, err))) {
        iso_free(j);
        return rc;
    }
    parallel(iso_n_slabs(j), threads, emit_slab, j);
    rc = iso_end(j, m, err);
    *ms = sf_now_ms() - t0;
    return rc;
}

/* A directory's files as the multipart/form-data body POST /isosurface takes for a DICOM series
 * (the order does not matter: slices are placed by their positions). NULL after saying why. */
static char *series_body(const char *dir, size_t *len)
{
    DIR *d = opendir(dir);
    if (!d) {
        perror(dir);
        return NULL;
    }
    char *body = NULL;
    size_t n = 0;
    FILE *out = open_memstream(&body, &n);
    struct dirent *e;
    bool ok = out != NULL;
    while (ok && (e = readdir(d))) {
        char path[4096];
        struct stat st;
        snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
        if (e->d_name[0] == '.' || stat(path, &st) || !S_ISREG(st.st_mode))
            continue;
        size_t flen;
        char *f = cli_read_all(path, &flen, (size_t)1 << 30);
        ok = f && fprintf(out, "--surfd-series\r\nContent-Disposition: form-data; name=\"slice\"; filename=\"%s\"\r\n\r\n",
                          e->d_name) > 0 && fwrite(f, 1, flen, out) == flen && fputs("\r\n", out) >= 0;
        free(f);
    }
    closedir(d);
    if (out) {
        ok = ok && fputs("--surfd-series--\r\n", out) >= 0;
        ok = fclose(out) == 0 && ok;
    }
    if (!ok) {
        free(body);
        fprintf(stderr, "surfd: %s: cannot read the series\n", dir);
        return NULL;
    }
    *len = n;
    return body;
}

void cmd_isosurface_usage(FILE *f)
{
    fprintf(f, "usage: surfd isosurface VOLUME.nrrd|.nhdr|.mha|.mhd|.nii|.nii.gz|.raw|DICOM-DIR --iso V [--dims X,Y,Z --type T "
               "[--spacing sx,sy,sz] [--origin x,y,z]]\n"
               "       surfd isosurface IMAGE.dcm --iso V [--segment N]  (one multi-frame image: Enhanced CT/MR, RT Dose in Gy,\n"
               "                        a Segmentation's segment N, iso 0.5)\n"
               "       surfd isosurface FREP.json [--iso V]\n"
               "                        [--levels 1-4 [--max-error MM] [--merge cells|pieces]] [--features none|sharp] [--closed true|false] [--name NAME] [--format raw|nrrd|mha|nifti|dicom|frep]\n"
               "                        [--label N | --labels all] (a label map: label N's surface, or every label's)\n"
               "                        [-o OUT.stl|.ply|.obj] [--threads N] [--repeat N] [--stats]\n"
               "                        [--edits N [--edit-size S]] [--isos V,V,...] [--check] (marching cubes kept,\n"
               "                        core/iso/kept.h: N edits of S^3 blocks that hold the surface, then each iso;\n"
               "                        their timings as JSON; --check: each mesh against a fresh extraction)\n"
               "       surfd matrix VOLUME|FREP.json [--iso V] [the volume's options above] [-o OUT.json]\n"
               "                        (its six relief matrices, seed 003: samples >= iso are the body)\n");
}

/* A detached header (volume_data_file: the shared .nhdr and .mhd and most tools' exports come so)
 * made whole with the data file it names, read beside it (volume_attach), as POST /isosurface
 * takes it. buf is freed; NULL when the file cannot be read. Other bodies are returned as they are
 * (a multi-file NRRD reaches volume_read and its answer). */
static char *attach_data(const char *path, char *buf, size_t *len)
{
    char file[4096];
    int line = volume_data_file(buf, *len, file, sizeof file);
    if (!line)
        return buf;
    const char *slash = strrchr(path, '/');
    size_t dn = file[0] == '/' || !slash ? 0 : (size_t)(slash - path) + 1, data_len = 0;
    char *data_path = malloc(dn + strlen(file) + 1), *data = NULL, *whole = NULL;
    if (data_path) {
        snprintf(data_path, dn + strlen(file) + 1, "%.*s%s", (int)dn, path, file);
        data = cli_read_all(data_path, &data_len, (size_t)1 << 34);
    }
    if (data && !(whole = volume_attach(buf, *len, line, data, data_len, len)))
        fprintf(stderr, "surfd: %s: out of memory\n", data_path);
    free(data_path), free(data), free(buf);
    return whole;
}

/* --labels all: every label's surface (core/iso/labels.h, the fastest of repeat), each label's
 * model resource in {"models": [...]} on stdout, its mesh in OUT-VALUE.EXT with -o OUT.EXT. */
static int labels_out(struct volume *v, const char *out, int repeat, double read_ms, bool stats, struct sf_err *err)
{
    struct iso_labels l = {0};
    double best = 1e300;
    int rc = 0;
    for (int r = 0; r < repeat && !rc; r++) {
        iso_labels_free(&l);
        double t = sf_now_ms();
        if (!(rc = iso_labels_extract(&v->g, v->n_labels, v->closed, 0, NULL, NULL, &l, err)))
            best = fmin(best, sf_now_ms() - t);
    }
    const char *ext = out ? strrchr(out, '.') : NULL;
    if (!rc && out && (!ext || !mesh_mime(ext + 1)))
        rc = sf_fail(err, SF_EINVAL, "-o", "the meshes are written as .stl, .ply or .obj");
    size_t *touch = rc ? NULL : malloc(sizeof *touch * ((size_t)v->n_labels + 1));
    if (!rc && !touch)
        rc = sf_fail(err, SF_ENOMEM, "", "out of memory");
    size_t all = 0;
    printf("{\"models\":[");
    for (int k = 1; k <= v->n_labels && !rc; k++) {
        double t = sf_now_ms();
        struct trimesh m;
        struct trimesh_stats st;
        char name[sizeof v->name], *json = NULL, *file = NULL;
        size_t file_len;
        volume_label_name(v, k, name, sizeof name);
        if ((rc = iso_labels_mesh(&l, k, touch, &m, err)))
            break;
        if (v->oblique)
            trimesh_turn(&m, v->g.origin, (const double(*)[3])v->axes);
        rc = trimesh_stats(&m, &st, err);
        if (!rc && out) {
            char path[4200];
            snprintf(path, sizeof path, "%.*s-%lld%s", (int)(ext - out), out, v->label_of[k - 1].value, ext);
            if (!(rc = mesh_encode(&m, ext + 1, &file, &file_len, err)))
                rc = cli_write_all(path, file, file_len) ? SF_EIO : 0;
        }
        double t1 = sf_now_ms();
        struct iso_model im = {"offline", name, v, &st, NULL, m.n_vert, m.n_tri, {read_ms, 0, best, t1 - t, read_ms + best + t1 - t}, 0, NULL,
                               k, touch};
        all += m.n_tri;
        trimesh_free(&m);
        if (!rc && !(json = iso_model_json(&im, err)))
            rc = err->code;
        if (!rc)
            printf("%s%s", k > 1 ? "," : "", json);
        free(json);
        free(file);
    }
    printf("]}\n");
    if (!rc && stats)
        fprintf(stderr, "labels: %.1f ms (best of %d, one thread), %zu triangles shared, %zu in the %d meshes, %ld "
                "junctions with a labelled centre\n", best, repeat, l.n_tri, all, v->n_labels, l.centres);
    free(touch);
    iso_labels_free(&l);
    return rc;
}

static int cmp_double(const void *p, const void *q)
{
    double a = *(const double *)p, b = *(const double *)q;
    return a < b ? -1 : a > b;
}

/* Whether k's mesh is a fresh extraction's of g at o, triangle for triangle (trimesh_differ). */
static bool kept_is_fresh(const struct iso_kept *k, const struct iso_grid *g, const struct iso_opts *o)
{
    struct trimesh a, b;
    uint32_t *ids;
    struct sf_err err = {0};
    if (iso_extract(g, o, NULL, &a, &err))
        return false;
    if (iso_kept_mesh(k, &b, &ids, &err)) {
        trimesh_free(&a);
        return false;
    }
    size_t differ;
    bool same = !trimesh_differ(&a, &b, &differ) && differ == 0;
    free(ids);
    trimesh_free(&a);
    trimesh_free(&b);
    return same;
}

/* --edits N --edit-size S --isos V,... (issue 45's bench): marching cubes kept (core/iso/kept.h);
 * N edits of S^3 blocks holding the surface (a ball of +400 painted into each, as the HTTP edit
 * bench does; blocks drawn by a fixed seed), then each iso in turn, timed; JSON on stdout. The
 * volume's samples (v->g) are edited in place, so that --check compares with fresh extractions. */
static int kept_bench(struct volume *v, int edits, int size, const char *isos, bool check, struct sf_err *err)
{
    struct iso_opts o = volume_iso_opts(v);
    if (volume_adaptive(v) || v->g.type != ISO_I16 || v->frep)
        return sf_fail(err, SF_EINVAL, "--edits", "the kept bench takes an int16 volume at levels=1");
    if (size < 2 || size > v->g.nx || size > v->g.ny || size > v->g.nz)
        return sf_fail(err, SF_EINVAL, "--edit-size", "an edit block fits in the volume");
    struct iso_kept *k;
    double t0 = sf_now_ms();
    int rc = iso_kept_begin(&v->g, &o, &k, err);
    if (rc)
        return rc;
    double begin = sf_now_ms() - t0;
    t0 = sf_now_ms();
    if ((rc = iso_kept_index(k, err))) { /* (the daemon's warm-up makes them after the model's answer) */
        iso_kept_free(k);
        return rc;
    }
    double index = sf_now_ms() - t0;
    int16_t *vol = (int16_t *)v->g.samples, *blk = malloc((size_t)size * size * size * sizeof *blk);
    double *ms = malloc(((size_t)edits + 1) * sizeof *ms), *cells = malloc(((size_t)edits + 1) * sizeof *cells);
    if (!blk || !ms || !cells) {
        free(blk), free(ms), free(cells);
        iso_kept_free(k);
        return sf_fail(err, SF_ENOMEM, "", "out of memory");
    }
    unsigned seed = 45;
    long added = 0, removed = 0;
    bool same = true;
    int nx = v->g.nx, ny = v->g.ny, nz = v->g.nz, c = size / 2;
    for (int e = 0; e < edits && !rc; e++) {
        int lo[3];
        for (int tries = 0; tries < 100000; tries++) { /* a block holding the surface */
            int dims[3] = {nx, ny, nz};
            for (int d = 0; d < 3; d++) {
                seed = seed * 1103515245u + 12345u;
                lo[d] = (int)((seed >> 8) % (unsigned)(dims[d] - size + 1));
            }
            int mn = INT16_MAX, mx = INT16_MIN;
            for (int z = 0; z < size; z++)
                for (int y = 0; y < size; y++)
                    for (int x = 0; x < size; x++) {
                        int s = vol[(lo[0] + x) + (size_t)nx * ((lo[1] + y) + (size_t)ny * (lo[2] + z))];
                        mn = s < mn ? s : mn, mx = s > mx ? s : mx;
                    }
            if (mn < o.iso && o.iso < mx)
                break;
        }
        for (int z = 0; z < size; z++)
            for (int y = 0; y < size; y++)
                for (int x = 0; x < size; x++) {
                    int s = vol[(lo[0] + x) + (size_t)nx * ((lo[1] + y) + (size_t)ny * (lo[2] + z))];
                    int r2 = (x - c) * (x - c) + (y - c) * (y - c) + (z - c) * (z - c);
                    blk[x + size * (y + size * z)] = (int16_t)(r2 < size * size * 30 / 256 && s < 32767 - 400 ? s + 400 : s);
                }
        struct iso_grid bg = {size, size, size, ISO_I16, blk, {1, 1, 1}, {0, 0, 0}};
        struct iso_edit ed;
        struct iso_change ch;
        double t = sf_now_ms();
        rc = iso_kept_edit(k, lo, &bg, &ed, &ch, err);
        ms[e] = sf_now_ms() - t;
        cells[e] = (double)ed.cells_rebuilt;
        added += (long)ch.n_added, removed += (long)ch.n_removed;
        iso_change_free(&ch);
        for (int z = 0; z < size && !rc; z++)
            for (int y = 0; y < size; y++)
                memcpy(vol + (lo[0]) + (size_t)nx * ((lo[1] + y) + (size_t)ny * (lo[2] + z)), blk + size * (y + size * z),
                       (size_t)size * sizeof *blk);
        if (!rc && check)
            same = same && kept_is_fresh(k, &v->g, &o);
    }
    double ms_max = 0;
    for (int e = 0; e < edits; e++)
        ms_max = ms[e] > ms_max ? ms[e] : ms_max;
    qsort(ms, (size_t)edits, sizeof *ms, cmp_double);
    qsort(cells, (size_t)edits, sizeof *cells, cmp_double);
    if (!rc)
        printf("{\"begin_ms\": %.3f, \"index_ms\": %.3f, \"bytes\": %zu, \"edits\": %d, \"edit_size\": %d, "
               "\"edit_ms_median\": %.3f, \"edit_ms_max\": %.3f, \"cells_rebuilt_median\": %.0f, "
               "\"triangles_added\": %ld, \"triangles_removed\": %ld, \"isos\": [",
               begin, index, iso_kept_bytes(k), edits, size, edits ? ms[edits / 2] : 0.0, ms_max,
               edits ? cells[edits / 2] : 0.0, added, removed);
    for (const char *p = isos; !rc && p && *p;) {
        char *end;
        double iso = strtod(p, &end);
        if (end == p) {
            rc = sf_fail(err, SF_EINVAL, "--isos", "a list of numbers");
            break;
        }
        struct iso_edit ed;
        struct iso_change ch;
        double t = sf_now_ms();
        rc = iso_kept_iso(k, iso, false, &ed, &ch, err); /* (as the daemon: it reads the mesh back whole) */
        double took = sf_now_ms() - t;
        if (!rc) {
            o.iso = iso;
            bool ok = !check || kept_is_fresh(k, &v->g, &o);
            same = same && ok;
            printf("%s{\"iso\": %g, \"ms\": %.3f, \"triangles\": %zu, \"cells_drawn\": %ld}", p == isos ? "" : ", ", iso,
                   took, ch.n_added, ed.cells_rebuilt);
        }
        iso_change_free(&ch);
        p = *end == ',' ? end + 1 : end;
    }
    t0 = sf_now_ms(); /* what the first edit after a new iso makes first */
    if (!rc && !(rc = iso_kept_index(k, err)))
        printf("], \"index_after_isos_ms\": %.3f, \"checked\": %s, \"equal_to_fresh\": %s, \"bytes_after\": %zu}\n",
               sf_now_ms() - t0, check ? "true" : "false", same ? "true" : "false", iso_kept_bytes(k));
    free(blk);
    free(ms);
    free(cells);
    iso_kept_free(k);
    return rc ? rc : same ? 0 : sf_fail(err, SF_EBACKEND, "", "a kept mesh differs from a fresh extraction");
}

int cmd_isosurface(int argc, char **argv)
{
    char options[512] = "";
    const char *out = NULL, *format = "";
    const char *isos = NULL;
    int threads = 1, repeat = 1, edits = 0, edit_size = 16;
    bool stats = false, check = false, bad = argc < 2;
    for (int k = 2; k < argc && !bad; k++) {
        size_t n = strlen(options);
        const char *a = argv[k];
        if (!strcmp(a, "--stats")) {
            stats = true;
        } else if (!strcmp(a, "--check")) {
            check = true;
        } else if (k + 1 < argc && !strcmp(a, "--edits")) {
            edits = atoi(argv[++k]);
        } else if (k + 1 < argc && !strcmp(a, "--edit-size")) {
            edit_size = atoi(argv[++k]);
        } else if (k + 1 < argc && !strcmp(a, "--isos")) {
            isos = argv[++k];
        } else if (k + 1 >= argc) {
            bad = true;
        } else if (!strcmp(a, "-o")) {
            out = argv[++k];
        } else if (!strcmp(a, "--threads")) {
            threads = atoi(argv[++k]);
        } else if (!strcmp(a, "--repeat")) {
            repeat = atoi(argv[++k]);
        } else if (!strcmp(a, "--format")) {
            format = argv[++k];
        } else if (!strcmp(a, "--iso") || !strcmp(a, "--dims") || !strcmp(a, "--type") || !strcmp(a, "--spacing") ||
                   !strcmp(a, "--origin") || !strcmp(a, "--closed") || !strcmp(a, "--name") || !strcmp(a, "--levels") ||
                   !strcmp(a, "--features") || !strcmp(a, "--merge") || !strcmp(a, "--segment") || !strcmp(a, "--label") ||
                   !strcmp(a, "--labels")) {
            snprintf(options + n, sizeof options - n, "%s%s=%s", n ? "&" : "", a + 2, argv[k + 1]);
            k++;
        } else if (!strcmp(a, "--max-error")) {
            snprintf(options + n, sizeof options - n, "%smax_error=%s", n ? "&" : "", argv[k + 1]);
            k++;
        } else {
            bad = true;
        }
    }
    if (bad || threads < 1 || threads > 64 || repeat < 1 || edits < 0) {
        cmd_isosurface_usage(stderr);
        return 2;
    }
    double t0 = sf_now_ms();
    size_t len;
    struct stat fs;
    bool dir = stat(argv[1], &fs) == 0 && S_ISDIR(fs.st_mode);
    char *buf = dir ? series_body(argv[1], &len) : cli_read_all(argv[1], &len, (size_t)1 << 34);
    if (buf && !dir)
        buf = attach_data(argv[1], buf, &len);
    if (!buf)
        return 1;
    struct volume v;
    struct sf_err err = {0};
    int rc = volume_read(buf, len, format, options, &v, &err);
    if (!rc && v.frep && v.frep->n_refs) {
        rc = sf_fail(&err, SF_EINVAL, v.frep->refs[0].pointer, "a volume primitive reads a stored model: post the "
                     "object to surfd serve (POST /isosurface)");
        volume_free(&v);
    }
    double t_read = sf_now_ms();
    if (!rc)
        volume_sample(&v, 0, v.g.nz, NULL, NULL); /* an FRep's grid (on this thread: the daemon's job uses its pool) */
    if (!strcmp(argv[0], "matrix")) { /* surfd matrix: the volume's six relief matrices (seed 003) */
        char *json = rc ? NULL : matrix_json_of_volume(&v, &err);
        rc = rc ? rc : json ? 0 : err.code;
        if (!rc && out && cli_write_all(out, json, strlen(json)))
            rc = SF_EIO;
        else if (!rc && !out)
            printf("%s\n", json);
        free(json);
        volume_free(&v);
        free(buf);
        if (rc && rc != SF_EIO)
            fprintf(stderr, "surfd: %s: %s%s%s\n", argv[1], err.message, err.pointer[0] ? " at " : "", err.pointer);
        return rc ? 1 : 0;
    }
    if (!rc && v.all_labels) {
        rc = labels_out(&v, out, repeat, t_read - t0, stats, &err);
        volume_free(&v);
        free(buf);
        if (rc && rc != SF_EIO)
            fprintf(stderr, "surfd: %s: %s%s%s\n", argv[1], err.message, err.pointer[0] ? " at " : "", err.pointer);
        return rc ? 1 : 0;
    }
    if (!rc && (edits || isos)) {
        iso_init();
        rc = kept_bench(&v, edits, edit_size, isos, check, &err);
        volume_free(&v);
        free(buf);
        if (rc)
            fprintf(stderr, "surfd: %s: %s%s%s\n", argv[1], err.message, err.pointer[0] ? " at " : "", err.pointer);
        return rc ? 1 : 0;
    }
    double t_sampled = sf_now_ms();
    iso_init();
    struct trimesh m = {0};
    struct iso_adapt_stats as = {0};
    double ms = 0, first = 0, best = 1e300;
    if (repeat > 1) /* later repeats reuse the memory freed, as a long-running process's allocator does */
        mallopt(M_MMAP_THRESHOLD, 1 << 30), mallopt(M_TRIM_THRESHOLD, 1 << 30);
    for (int r = 0; r < repeat && !rc; r++) { /* the first (cold) and the fastest (warm) */
        trimesh_free(&m);
        if (!(rc = extract(&v, threads, &m, &as, &ms, &err)) && ms < best)
            best = ms;
        if (r == 0)
            first = ms;
    }
    double t_extract = sf_now_ms();
    if (!rc)
        rc = volume_mesh_empty(&v, &m, &err);
    if (!rc && v.oblique)
        trimesh_turn(&m, v.g.origin, (const double(*)[3])v.axes);
    struct trimesh_stats st;
    if (!rc)
        rc = trimesh_stats(&m, &st, &err);
    double t_measure = sf_now_ms();
    char *json = NULL, *file = NULL;
    size_t file_len = 0;
    const char *ext = out ? strrchr(out, '.') : NULL;
    if (!rc && out) {
        if (!ext || !mesh_mime(ext + 1))
            rc = sf_fail(&err, SF_EINVAL, "-o", "the mesh is written as .stl, .ply or .obj");
        else if (!(rc = mesh_encode(&m, ext + 1, &file, &file_len, &err)))
            rc = cli_write_all(out, file, file_len) ? SF_EIO : 0;
    }
    if (!rc) {
        struct iso_model im = {"offline", v.name, &v, &st, volume_adaptive(&v) ? &as : NULL, m.n_vert, m.n_tri,
                               {t_read - t0, t_sampled - t_read, best, t_measure - t_extract, t_measure - t0}, 0, NULL,
                               v.has_label, NULL};
        if (!(json = iso_model_json(&im, &err)))
            rc = err.code;
    }
    free(file);
    trimesh_free(&m);
    volume_free(&v);
    free(buf);
    if (rc) {
        if (rc != SF_EIO)
            fprintf(stderr, "surfd: %s: %s%s%s\n", argv[1], err.message, err.pointer[0] ? " at " : "", err.pointer);
        return 1;
    }
    printf("%s\n", json);
    if (stats)
        fprintf(stderr, "extract %.1f ms cold, %.1f ms warm (best of %d), %d thread%s\n", first, best, repeat, threads,
                threads == 1 ? "" : "s");
    free(json);
    return 0;
}
