/* surfctl.c - the command-line client of surfd: speaks only HTTP (libcurl), reads SURFD_URL
 * (default http://127.0.0.1:8080) and SURFD_TOKEN from the environment (a daemon signed by a site's
 * own certificate authority: --cacert FILE or SURFD_CACERT). A command for every route (USAGE
 * below, each with its --help); long jobs are followed with a progress bar on a
 * terminal, a plain line every 10 % with an ETA otherwise (--progress=bar|plain|none), polling
 * from 100 ms backing off to 2 s; a failed or cancelled job prints its problem.
 *
 * Exit codes: 0 done; 1 the job failed or was cancelled; 2 usage; 3 surfd unreachable;
 * 4 request refused (4xx: the problem's detail and pointer go to stderr); 5 server error (5xx). */
#include <ctype.h>
#include <curl/curl.h>
#include <dirent.h>
#include <jansson.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "../api/formats.h"

enum { EXIT_JOB = 1, EXIT_USAGE = 2, EXIT_UNREACHABLE = 3, EXIT_REFUSED = 4, EXIT_SERVER = 5 };

#define MAX_RESPONSE (1L << 30) /* a result larger than 1 GiB is refused */

enum progress_mode { PROGRESS_AUTO, PROGRESS_BAR, PROGRESS_PLAIN, PROGRESS_NONE };
static enum progress_mode progress_mode = PROGRESS_AUTO;

struct buf {
    char *data;
    size_t len;
};

/* Appends n bytes at p to b (kept 0-terminated): false when out of memory. */
static bool buf_add(struct buf *b, const void *p, size_t n)
{
    char *d = realloc(b->data, b->len + n + 1);
    if (!d)
        return false;
    memcpy(d + b->len, p, n);
    b->data = d;
    b->len += n;
    b->data[b->len] = 0;
    return true;
}

static size_t on_data(char *p, size_t size, size_t n, void *arg)
{
    struct buf *b = arg;
    size_t add = size * n;
    return b->len + add <= (size_t)MAX_RESPONSE && buf_add(b, p, add) ? add : 0;
}

struct response {
    long status;
    struct buf body;
    char job_id[64];
    char content_type[64];
};

static size_t on_header(char *p, size_t size, size_t n, void *arg)
{
    struct response *r = arg;
    size_t len = size * n;
    if (len > 9 && !strncasecmp(p, "X-Job-Id:", 9))
        sscanf(p + 9, " %63s", r->job_id);
    return len;
}

static const char *cacert; /* --cacert FILE (else SURFD_CACERT): the CA bundle TLS is checked against */

static const char *base_url(void)
{
    const char *u = getenv("SURFD_URL");
    return u && *u ? u : "http://127.0.0.1:8080";
}

/* One request. body may be NULL (GET, or POST without body when post is true). */
static int request(const char *method, const char *path, const char *body, size_t body_len, const char *type,
                   const char *prefer, struct response *r)
{
    memset(r, 0, sizeof *r);
    CURL *c = curl_easy_init();
    if (!c)
        return EXIT_UNREACHABLE;
    char url[2048];
    snprintf(url, sizeof url, "%s%s", base_url(), path);
    struct curl_slist *h = NULL;
    char line[1200];
    const char *tok = getenv("SURFD_TOKEN");
    if (tok && *tok) {
        snprintf(line, sizeof line, "Authorization: Bearer %s", tok);
        h = curl_slist_append(h, line);
    }
    if (type) {
        snprintf(line, sizeof line, "Content-Type: %s", type);
        h = curl_slist_append(h, line);
    }
    if (prefer) {
        snprintf(line, sizeof line, "Prefer: %s", prefer);
        h = curl_slist_append(h, line);
    }
    curl_easy_setopt(c, CURLOPT_URL, url);
    curl_easy_setopt(c, CURLOPT_CUSTOMREQUEST, method);
    if (body || !strcmp(method, "POST")) {
        curl_easy_setopt(c, CURLOPT_POSTFIELDS, body ? body : "");
        curl_easy_setopt(c, CURLOPT_POSTFIELDSIZE_LARGE, (curl_off_t)body_len);
    }
    curl_easy_setopt(c, CURLOPT_HTTPHEADER, h);
    curl_easy_setopt(c, CURLOPT_WRITEFUNCTION, on_data);
    curl_easy_setopt(c, CURLOPT_WRITEDATA, &r->body);
    curl_easy_setopt(c, CURLOPT_HEADERFUNCTION, on_header);
    curl_easy_setopt(c, CURLOPT_HEADERDATA, r);
    curl_easy_setopt(c, CURLOPT_CONNECTTIMEOUT, 10L);
    if (cacert)
        curl_easy_setopt(c, CURLOPT_CAINFO, cacert);
    CURLcode rc = curl_easy_perform(c);
    char *ct = NULL;
    curl_easy_getinfo(c, CURLINFO_RESPONSE_CODE, &r->status);
    curl_easy_getinfo(c, CURLINFO_CONTENT_TYPE, &ct);
    if (ct)
        snprintf(r->content_type, sizeof r->content_type, "%s", ct);
    curl_slist_free_all(h);
    curl_easy_cleanup(c);
    if (rc != CURLE_OK) {
        fprintf(stderr, "surfctl: %s: %s\n", url, curl_easy_strerror(rc));
        return EXIT_UNREACHABLE;
    }
    return 0;
}

/* Prints a problem+json body; returns the exit code of its status. */
static int report(const struct response *r)
{
    json_t *p = r->body.data ? json_loads(r->body.data, 0, NULL) : NULL;
    const char *detail = p ? json_string_value(json_object_get(p, "detail")) : NULL;
    json_t *errs = p ? json_object_get(p, "errors") : NULL;
    const char *ptr = errs ? json_string_value(json_object_get(json_array_get(errs, 0), "pointer")) : NULL;
    fprintf(stderr, "surfctl: %ld %s%s%s\n", r->status, detail ? detail : (r->body.data ? r->body.data : ""),
            ptr ? " at " : "", ptr ? ptr : "");
    json_decref(p);
    return r->status >= 500 ? EXIT_SERVER : EXIT_REFUSED;
}

static int write_file(const char *path, const struct buf *b)
{
    FILE *f = strcmp(path, "-") ? fopen(path, "wb") : stdout;
    if (!f || fwrite(b->data, 1, b->len, f) != b->len || (f != stdout && fclose(f))) {
        perror(path);
        return EXIT_JOB;
    }
    return 0;
}

static char *read_file(const char *path, size_t *len)
{
    FILE *f = fopen(path, "rb");
    if (!f) {
        perror(path);
        return NULL;
    }
    struct buf b = {0};
    char chunk[65536];
    size_t n;
    while ((n = fread(chunk, 1, sizeof chunk, f)) > 0)
        if (on_data(chunk, 1, n, &b) != n) {
            fclose(f);
            free(b.data);
            return NULL;
        }
    fclose(f);
    *len = b.len;
    return b.data ? b.data : strdup("");
}

/* A file's media type on route by its extension (api/formats.h's table, as the daemon reads it);
 * application/octet-stream when it names none (the daemon sniffs it, or reads raw samples). */
static const char *type_of(const char *path, unsigned route)
{
    const struct input_format *f = input_format_of_path(path, route);
    return f ? f->media[0] : "application/octet-stream";
}

/* POSTs the file to route + query (the query "" or "?name=value&..."). 0 and *r, or an exit code. */
static int post_file(const char *route, const char *query, const char *file, const char *type, const char *prefer,
                     struct response *r)
{
    size_t len;
    char *body = read_file(file, &len);
    if (!body)
        return EXIT_USAGE;
    char path[768];
    snprintf(path, sizeof path, "%s%s", route, query);
    int rc = request("POST", path, body, len, type, prefer, r);
    free(body);
    return rc;
}

static int by_name(const void *a, const void *b) { return strcmp(*(char *const *)a, *(char *const *)b); }

/* Whether a file of a series' directory is one of its images: DICOM ("DICM" after the preamble,
 * or a first element of group 0002 or 0008 without one), and not the media's DICOMDIR. */
static bool series_image(const char *name, const char *data, size_t len)
{
    if (!strcasecmp(name, "DICOMDIR"))
        return false;
    return (len >= 132 && !memcmp(data + 128, "DICM", 4)) || (len >= 8 && data[1] == 0 && (data[0] == 2 || data[0] == 8));
}

/* A multipart/form-data body's boundary, and its Content-Type with it into type. */
static void multipart_start(char boundary[48], char *type, size_t cap)
{
    snprintf(boundary, 48, "surfctl-%08lx%08lx", (unsigned long)time(NULL), (unsigned long)getpid() * 2654435761ul);
    snprintf(type, cap, "multipart/form-data; boundary=%s", boundary);
}

/* Appends one part (form field name, its file's name and type, and its bytes) to b; false when out
 * of memory. */
static bool multipart_add(struct buf *b, const char *boundary, const char *name, const char *filename,
                          const char *type, const char *data, size_t len)
{
    char head[512];
    int hn = snprintf(head, sizeof head, "--%s\r\nContent-Disposition: form-data; name=\"%s\"; filename=\"%s\"\r\n"
                      "Content-Type: %s\r\n\r\n", boundary, name, filename, type);
    return hn > 0 && hn < (int)sizeof head && buf_add(b, head, (size_t)hn) && buf_add(b, data, len) &&
           buf_add(b, "\r\n", 2);
}

static bool multipart_end(struct buf *b, const char *boundary)
{
    char tail[64];
    int tn = snprintf(tail, sizeof tail, "--%s--\r\n", boundary);
    return buf_add(b, tail, (size_t)tn);
}

/* The data file a detached header names (NRRD's "data file: F", MetaImage's "ElementDataFile = F",
 * not LOCAL, a list or a pattern) into file; false for anything else. */
static bool data_file_of(const char *data, size_t len, char *file, size_t cap)
{
    bool nrrd = len >= 4 && !memcmp(data, "NRRD", 4);
    if (!nrrd && !(len >= 5 && (!memcmp(data, "NDims", 5) || (len >= 10 && !memcmp(data, "ObjectType", 10)))))
        return false;
    for (size_t at = 0, line = 0; at < len && line < 4096; line++) { /* (the daemon's HEADER_MAX_LINES) */
        const char *nl = memchr(data + at, '\n', len - at), *s = data + at;
        size_t n = nl ? (size_t)(nl - s) : len - at;
        at += n + 1;
        if (nrrd && (n == 0 || (n == 1 && s[0] == '\r'))) /* the end of an NRRD header */
            return false;
        const char *sep = memchr(s, nrrd ? ':' : '=', n);
        if (!sep)
            continue;
        size_t kn = (size_t)(sep - s);
        while (kn && s[kn - 1] == ' ')
            kn--;
        if (!((kn == 9 && !memcmp(s, "data file", 9)) || (kn == 8 && !memcmp(s, "datafile", 8)) ||
              (kn == 15 && !memcmp(s, "ElementDataFile", 15))))
            continue;
        const char *v = sep + 1 + (nrrd && sep[1] == '='), *end = s + n;
        while (v < end && *v == ' ')
            v++;
        while (end > v && (end[-1] == ' ' || end[-1] == '\r'))
            end--;
        size_t vn = (size_t)(end - v);
        if (!vn || vn >= cap || (vn == 5 && !memcmp(v, "LOCAL", 5)) || (vn >= 4 && !memcmp(v, "LIST", 4)) ||
            memchr(v, '%', vn))
            return false;
        memcpy(file, v, vn), file[vn] = 0;
        return true;
    }
    return false;
}

/* A detached header (path, its bytes hdr) and the data file it names, beside it, as the two parts
 * of multipart/form-data POST /isosurface takes ("header" and "data", each under its own file
 * name). 0, or an exit code. */
static int pair_body(const char *path, const char *hdr, size_t hlen, const char *file, struct buf *b, char *type,
                     size_t cap)
{
    const char *slash = strrchr(path, '/'), *base = strrchr(file, '/');
    char data_path[4096], boundary[48];
    snprintf(data_path, sizeof data_path, "%.*s%s", file[0] == '/' || !slash ? 0 : (int)(slash - path + 1), path, file);
    size_t len;
    char *data = read_file(data_path, &len);
    if (!data)
        return EXIT_USAGE;
    multipart_start(boundary, type, cap);
    bool ok = multipart_add(b, boundary, "header", slash ? slash + 1 : path, "text/plain", hdr, hlen) &&
              multipart_add(b, boundary, "data", base ? base + 1 : file, "application/octet-stream", data, len) &&
              multipart_end(b, boundary);
    free(data);
    if (!ok)
        fprintf(stderr, "surfctl: out of memory\n");
    return ok ? 0 : EXIT_USAGE;
}

/* A directory's images (a DICOM series, one image a file; hidden files, the DICOMDIR and files that
 * are not DICOM skipped, in name order) as multipart/form-data, one part "slice" a file, as curl
 * -F slice=@FILE sends them; the parts are named slice0001.dcm ... (a series' own file names may
 * name the patient). The type (with its boundary) into type. 0, or an exit code. */
static int series_body(const char *dir, struct buf *b, char *type, size_t cap)
{
    DIR *d = opendir(dir);
    if (!d) {
        perror(dir);
        return EXIT_USAGE;
    }
    char **names = NULL;
    size_t n = 0;
    for (struct dirent *e; (e = readdir(d));) {
        char path[4096];
        struct stat st;
        snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
        if (e->d_name[0] == '.' || stat(path, &st) || !S_ISREG(st.st_mode))
            continue;
        char **more = realloc(names, (n + 1) * sizeof *names);
        if (more)
            names = more;
        if (!more || !(names[n] = strdup(path))) {
            closedir(d);
            for (size_t k = 0; k < n; k++)
                free(names[k]);
            free(names);
            fprintf(stderr, "surfctl: out of memory listing %s\n", dir);
            return EXIT_USAGE;
        }
        n++;
    }
    closedir(d);
    qsort(names, n, sizeof *names, by_name);
    char boundary[48];
    multipart_start(boundary, type, cap);
    int rc = n ? 0 : (fprintf(stderr, "surfctl: %s holds no files\n", dir), EXIT_USAGE);
    size_t parts = 0;
    for (size_t k = 0; k < n && !rc; k++) {
        size_t len;
        char *data = read_file(names[k], &len), filename[32];
        const char *base = strrchr(names[k], '/') + 1;
        if (data && !series_image(base, data, len)) {
            fprintf(stderr, "surfctl: %s is not an image of the series; left out\n", names[k]);
            free(data);
            continue;
        }
        snprintf(filename, sizeof filename, "slice%04zu.dcm", ++parts);
        if (!data || !multipart_add(b, boundary, "slice", filename, "application/dicom", data, len))
            rc = EXIT_USAGE;
        free(data);
    }
    if (!rc && !multipart_end(b, boundary))
        rc = EXIT_USAGE;
    for (size_t k = 0; k < n; k++)
        free(names[k]);
    free(names);
    return rc;
}

/* POSTs a volume to route + query: a file, a detached header and the data file it names (pair_body),
 * or a directory's files as a DICOM series (series_body). */
static int post_volume(const char *route, const char *query, const char *file, const char *prefer, struct response *r)
{
    struct stat st;
    struct buf b = {0};
    char type[96], path[768], data_file[1024];
    int rc;
    if (stat(file, &st) || !S_ISDIR(st.st_mode)) {
        size_t len;
        char *body = read_file(file, &len);
        if (!body)
            return EXIT_USAGE;
        if (data_file_of(body, len, data_file, sizeof data_file)) {
            rc = pair_body(file, body, len, data_file, &b, type, sizeof type);
            free(body);
        } else {
            b = (struct buf){body, len};
            snprintf(type, sizeof type, "%s", type_of(file, IN_ISOSURFACE));
            rc = 0;
        }
    } else {
        rc = series_body(file, &b, type, sizeof type);
    }
    snprintf(path, sizeof path, "%s%s", route, query);
    if (!rc)
        rc = request("POST", path, b.data, b.len, type, prefer, r);
    free(b.data);
    return rc;
}

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec + ts.tv_nsec / 1e9;
}

/* A job's problem (its "error" member) on stderr. */
static void job_problem(json_t *job, const char *id, const char *state)
{
    json_t *e = json_object_get(job, "error");
    const char *detail = json_string_value(json_object_get(e, "detail"));
    const char *ptr = json_string_value(json_object_get(json_array_get(json_object_get(e, "errors"), 0), "pointer"));
    fprintf(stderr, "surfctl: job %s %s%s%s%s%s\n", id, state, detail ? ": " : "", detail ? detail : "",
            ptr ? " at " : "", ptr ? ptr : "");
}

/* Polls the job until it ends (from 100 ms, backing off to 2 s), showing its progress on stderr
 * as the mode says; a job that did not succeed prints its problem. */
static int wait_job(const char *id, char *state, size_t state_len)
{
    char path[128];
    snprintf(path, sizeof path, "/jobs/%s", id);
    enum progress_mode mode = progress_mode == PROGRESS_AUTO ? (isatty(2) ? PROGRESS_BAR : PROGRESS_PLAIN) : progress_mode;
    double t0 = now_s(), wait = 0.1;
    int shown = -1; /* the last tenth a plain line was printed for */
    for (;;) {
        struct response r;
        int rc = request("GET", path, NULL, 0, NULL, NULL, &r);
        if (rc)
            return rc;
        if (r.status != 200) {
            rc = report(&r);
            free(r.body.data);
            return rc;
        }
        json_t *j = json_loads(r.body.data, 0, NULL);
        const char *s = j ? json_string_value(json_object_get(j, "state")) : "?";
        double progress = j ? json_number_value(json_object_get(j, "progress")) : 0;
        snprintf(state, state_len, "%s", s ? s : "?");
        free(r.body.data);
        bool done = strcmp(state, "queued") && strcmp(state, "running");
        if (mode == PROGRESS_BAR) {
            int w = (int)(progress * 40 + 0.5);
            fprintf(stderr, "\r%s [%.*s%*s] %3.0f%% %-9s", id, w, "########################################", 40 - w,
                    "", progress * 100, state);
            if (done)
                fputc('\n', stderr);
        } else if (mode == PROGRESS_PLAIN && ((int)(progress * 10) > shown || done)) {
            shown = (int)(progress * 10);
            double el = now_s() - t0;
            if (progress > 0.0 && !done)
                fprintf(stderr, "surfctl: job %s %3.0f%% %s, ETA %.0f s\n", id, progress * 100, state,
                        el * (1.0 - progress) / progress);
            else
                fprintf(stderr, "surfctl: job %s %3.0f%% %s\n", id, progress * 100, state);
        }
        if (done && strcmp(state, "succeeded") && j)
            job_problem(j, id, state);
        json_decref(j);
        if (done)
            return 0;
        struct timespec ts = {(time_t)wait, (long)((wait - (time_t)wait) * 1e9)};
        nanosleep(&ts, NULL);
        wait = wait * 1.5 < 2.0 ? wait * 1.5 : 2.0;
    }
}

static int fetch_result(const char *id, const char *out)
{
    char path[128];
    snprintf(path, sizeof path, "/jobs/%s/result", id);
    struct response r;
    int rc = request("GET", path, NULL, 0, NULL, NULL, &r);
    if (!rc)
        rc = r.status == 200 ? write_file(out, &r.body) : (r.status == 409 || r.status == 422 ? (report(&r), EXIT_JOB) : report(&r));
    free(r.body.data);
    return rc;
}

/* Adds "--name value" to query as ?name=value (or &name=value) when name is one of names ("-" in
 * the flag, "_" in the query: --max-error is ?max_error). */
static bool query_arg(const char *a, const char *v, const char *const *names, char *query, size_t cap)
{
    char flag[32];
    snprintf(flag, sizeof flag, "%s", a[0] == '-' && a[1] == '-' ? a + 2 : "");
    for (char *c = flag; *c; c++)
        *c = *c == '-' ? '_' : *c;
    for (int k = 0; names[k]; k++)
        if (v && flag[0] && !strcmp(flag, names[k])) {
            size_t n = strlen(query);
            n += (size_t)snprintf(query + n, cap - n, "%c%s=", n ? '&' : '?', names[k]);
            for (const char *c = v; *c && n + 4 < cap; c++) /* percent-encoded: --view +x is view=%2Bx */
                n += (size_t)(isalnum((unsigned char)*c) || strchr("-._~,", *c)
                                  ? snprintf(query + n, cap - n, "%c", *c)
                                  : snprintf(query + n, cap - n, "%%%02X", (unsigned char)*c));
            return true;
        }
    return false;
}

/* A job still running when its request answered 202: followed to its end, its result to out. */
static int follow(const char *id, const char *out)
{
    char state[32];
    int rc = wait_job(id, state, sizeof state);
    if (!rc && strcmp(state, "succeeded"))
        rc = EXIT_JOB; /* its problem printed */
    return rc ? rc : fetch_result(id, out);
}

/* Each command's usage: printed by `surfctl CMD --help` (stdout, exit 0) and on a usage error. */
static const char *const USAGE[][2] = {
    {"render", "surfctl render SCENE -o OUT [--async] [--method M] [--width W] [--height H] [--output png|exr|tiff]\n"
               "               [--azimuth DEG --elevation DEG] [--eye X,Y,Z --target X,Y,Z] [--up X,Y,Z] [--fov DEG]\n"
               "               [--projection perspective|orthographic] [--view +x|-x|+y|-y|+z|-z] [--view-height H]\n"
               "    POST /render: SCENE is scene JSON, .bpt, VRML (.nurbs, .wrl) or IGES (.igs, .iges); the image to OUT\n"},
    {"model", "surfctl model CONTOURS [-o OUT.stl|.ply|.obj|.vtp|.vtk] [--method M] [--caps flat|slab|dome]\n"
              "              [--roi NAME] [--parameterisation arc-length|polar]\n"
              "    POST /model: contour JSON, an RT Structure Set (.dcm: every ROI, or --roi) or a matrix model;\n"
              "    the model resource on stdout, its (first model's) mesh to OUT\n"},
    {"volume", "surfctl volume CONTOURS|SCENE [--method M] [--caps flat|slab|dome] [--roi NAME] [--parameterisation P]\n"
               "    POST /volume: the volume figures on stdout, nothing stored (a scene's, .igs too: area and\n"
               "    the volume its surfaces close)\n"},
    {"isosurface", "surfctl isosurface VOLUME --iso V -o OUT.stl|.ply|.obj [--dims X,Y,Z --type T --spacing S --origin O]\n"
                   "                   [--levels 1-4 [--max-error MM] [--merge cells|pieces]] [--features none|sharp] [--closed true|false] [--name N]\n"
                   "                   [--segment N] [--label N | --labels all] (a label map, no --iso: label N's model,\n"
                   "                   or one a label, each label's mesh to OUT-N.stl)\n"
                   "    POST /isosurface: VOLUME is .nrrd, .mha, NIfTI (.nii, .nii.gz), raw samples, a directory of a DICOM\n"
                   "    series' images (each file a part), one multi-frame DICOM image (.dcm: an Enhanced CT or MR, an RT\n"
                   "    Dose, iso in Gy, or a Segmentation's segment N, iso 0.5), or an FRep object as .json\n"},
    {"edit", "surfctl edit MODEL BLOCK --region X0,Y0,Z0,NX,NY,NZ [-o OUT.stl|.ply|.obj | -o OUT --since V]\n"
             "    POST /models/MODEL/edit: BLOCK is the region's raw samples in the model's sample type; with --since\n"
             "    V, OUT the mesh delta from version V (what a client holding V applies)\n"},
    {"iso", "surfctl iso MODEL VALUE [-o OUT.stl|.ply|.obj | -o OUT --since V]\n"
            "    POST /models/MODEL/iso?value=VALUE: the model at a new iso, as its next version\n"},
    {"matrix", "surfctl matrix VOLUME -o OUT.json [--iso V --dims X,Y,Z --type T --spacing S --origin O]\n"
               "surfctl matrix --model ID [--size N,M,K] -o OUT.json\n"
               "    POST /matrix-model: the six relief matrices of a volume or of a stored model\n"},
    {"models", "surfctl models [ID]\n    GET /models (the list) or GET /models/ID (one model's resource)\n"},
    {"mesh", "surfctl mesh ID -o OUT [--format stl|ply|obj|vtp|vtk|delta] [--tolerance MM] [--since V]\n"
             "    GET /models/ID/mesh: the format from --format, else OUT's extension; delta: the changes from\n"
             "    version V (0, the default: the whole mesh)\n"},
    {"view", "surfctl view ID -o OUT.png [--width W --height H --azimuth DEG --elevation DEG --output FMT ...]\n"
             "    GET /models/ID/render, with render's camera options\n"},
    {"patches", "surfctl patches ID [-o OUT.json]\n    GET /models/ID/patches: the model's surfaces as scene JSON (stdout without -o)\n"},
    {"rtstruct", "surfctl rtstruct ID -o OUT.dcm [--spacing MM] [--format seg]\n"
                 "    GET /models/ID/rtstruct: the model as a DICOM RT Structure Set, its contours --spacing apart\n"
                 "    (default: a contour model's own slices, an isosurface's grid); --format seg: a DICOM\n"
                 "    Segmentation on its CT's grid (or --spacing's)\n"},
    {"delete", "surfctl delete ID\n    DELETE /models/ID\n"},
    {"series", "surfctl series [UID] [--delete]\n"
               "    GET /series (the DICOM series received or pulled), GET /series/UID (one, with its geometry),\n"
               "    or DELETE /series/UID\n"},
    {"studies", "surfctl studies PACS [KEY=VALUE ...]\n"
                "    GET /pacs/PACS/studies?KEY=VALUE...: a search of a configured PACS (PatientID=, StudyDate=...)\n"},
    {"pull", "surfctl pull PACS STUDY_UID [SERIES_UID]\n"
             "    POST /series/pull: a study's series (or one) from a configured PACS into the store, followed\n"},
    {"send", "surfctl send ID PACS [--as rtstruct|dicom-stl] [--spacing MM]\n"
             "    POST /models/ID/send: the model to a configured PACS, followed; what the PACS said of it\n"},
    {"jobs", "surfctl jobs [--state queued|running|succeeded|failed|cancelled]\n    GET /jobs\n"},
    {"job", "surfctl job ID\n    GET /jobs/ID\n"},
    {"wait", "surfctl wait ID [-o OUT]\n    follows the job to its end (its result to OUT)\n"},
    {"result", "surfctl result ID -o OUT\n    GET /jobs/ID/result\n"},
    {"cancel", "surfctl cancel ID\n    POST /jobs/ID/cancel\n"},
};
#define N_USAGE (sizeof USAGE / sizeof *USAGE)

static void usage_to(FILE *f, const char *cmd)
{
    for (size_t k = 0; k < N_USAGE; k++)
        if (!cmd || !strcmp(cmd, USAGE[k][0]))
            fprintf(f, "%s", USAGE[k][1]);
    if (!cmd)
        fprintf(f, "options of every command: --progress=bar|plain|none (default: bar on a terminal, else plain)\n"
                   "              --cacert FILE: the certificate authority a TLS daemon is checked against\n"
                   "environment: SURFD_URL (default http://127.0.0.1:8080), SURFD_TOKEN, SURFD_CACERT (as --cacert)\n"
                   "exit: 0 done, 1 the job failed or was cancelled, 2 usage, 3 surfd unreachable, 4 refused (4xx), 5 server error\n");
}

static const char *current_cmd;
static int usage(void)
{
    usage_to(stderr, current_cmd);
    return EXIT_USAGE;
}

/* A command's FILE, -o OUT (when out is not NULL), --async (when async is not NULL) and the query
 * options of names: false on anything else. */
static bool read_args(int argc, char **argv, const char *const *names, const char **file, const char **out,
                      bool *async, char *query, size_t cap)
{
    for (int k = 0; k < argc; k++) {
        const char *a = argv[k], *v = k + 1 < argc ? argv[k + 1] : NULL;
        if (out && !strcmp(a, "-o") && v)
            *out = v, k++;
        else if (async && !strcmp(a, "--async"))
            *async = true;
        else if (query_arg(a, v, names, query, cap))
            k++;
        else if (a[0] != '-' && !*file)
            *file = a;
        else
            return false;
    }
    return true;
}

static const char *const RENDER_OPTIONS[] = {"method", "width", "height", "output", "format", "azimuth", "elevation",
                                             "eye", "target", "up", "fov", "projection", "view", "view_height",
                                             "shadows", NULL};

static int cmd_render(int argc, char **argv)
{
    const char *file = NULL, *out = NULL;
    char query[1024] = "";
    bool async = false;
    if (!read_args(argc, argv, RENDER_OPTIONS, &file, &out, &async, query, sizeof query) || !file || (!out && !async))
        return usage();
    struct response r;
    int rc = post_file("/render", query, file, type_of(file, IN_RENDER), async ? "respond-async" : NULL, &r);
    if (rc)
        return rc;
    if (r.status == 200) {
        rc = write_file(out, &r.body);
    } else if (r.status == 202 && async) {
        printf("%s\n", r.job_id);
    } else if (r.status == 202) { /* the sync wait ran out: keep waiting here */
        rc = follow(r.job_id, out);
    } else {
        rc = r.status == 422 && r.job_id[0] ? (report(&r), EXIT_JOB) : report(&r);
    }
    free(r.body.data);
    return rc;
}

/* The job of a 202 answer r followed to its end, its result's answer into r (the 202's freed). */
static int job_answer(struct response *r)
{
    char id[64], state[32], path[128];
    snprintf(id, sizeof id, "%s", r->job_id);
    free(r->body.data);
    r->body.data = NULL;
    int rc = wait_job(id, state, sizeof state);
    if (rc)
        return rc;
    if (strcmp(state, "succeeded"))
        return EXIT_JOB; /* its problem printed */
    snprintf(path, sizeof path, "/jobs/%s/result", id);
    return request("GET", path, NULL, 0, NULL, NULL, r);
}

/* POSTs FILE (NULL: no body) to route + query as a job, followed to its end: 0 with the result's
 * answer in *r (its status the route's: 200, 201), or an exit code (the problem printed). */
static int run_job(const char *route, const char *query, const char *file, const char *type, struct response *r)
{
    char path[768];
    snprintf(path, sizeof path, "%s%s", route, query);
    int rc = file ? post_file(route, query, file, type, "respond-async", r)
                  : request("POST", path, NULL, 0, NULL, "respond-async", r);
    if (!rc && r->status == 202)
        rc = job_answer(r);
    if (!rc && r->status >= 300) {
        rc = (r->status == 409 || r->status == 422) && r->job_id[0] ? (report(r), EXIT_JOB) : report(r);
        free(r->body.data);
        r->body.data = NULL;
    }
    return rc;
}

/* GET path into out, following the job when the answer is a 202 (longer than the server's wait). */
static int get_file(const char *path, const char *out)
{
    struct response r;
    int rc = request("GET", path, NULL, 0, NULL, NULL, &r);
    if (rc)
        return rc;
    if (r.status == 202)
        rc = follow(r.job_id, out);
    else
        rc = r.status == 200 ? write_file(out, &r.body) : report(&r);
    free(r.body.data);
    return rc;
}

/* The mesh format an output file's extension names (.dcm: a DICOM Encapsulated STL). */
static const char *mesh_format_of(const char *out)
{
    const char *ext = strrchr(out, '.');
    return !ext ? "stl" : strcmp(ext, ".dcm") ? ext + 1 : "dicom-stl";
}

/* Model id's mesh to out (its format from the extension), following the mesh job when it is long. */
static int download_mesh(const char *id, const char *out)
{
    char path[160];
    snprintf(path, sizeof path, "/models/%.64s/mesh?format=%s", id, mesh_format_of(out));
    return get_file(path, out);
}

/* POST /isosurface, the job followed with the progress bar, the model resource on stdout and
 * its mesh written to OUT (format from its extension). */
static int cmd_isosurface(int argc, char **argv)
{
    static const char *const OPTIONS[] = {"iso", "dims", "type", "spacing", "origin", "closed", "name", "levels",
                                          "max_error", "merge", "features", "segment", "label", "labels", NULL};
    const char *file = NULL, *out = NULL;
    char query[600] = "";
    if (!read_args(argc, argv, OPTIONS, &file, &out, NULL, query, sizeof query))
        return usage();
    const char *ext = out ? strrchr(out, '.') : NULL;
    if (!file || !ext || (strcmp(ext, ".stl") && strcmp(ext, ".ply") && strcmp(ext, ".obj")))
        return usage();
    struct response r;
    int rc = post_volume("/isosurface", query, file, "respond-async", &r);
    if (rc)
        return rc;
    if (r.status != 202) {
        rc = report(&r);
        free(r.body.data);
        return rc;
    }
    char id[64];
    snprintf(id, sizeof id, "%s", r.job_id);
    if ((rc = job_answer(&r)))
        return rc;
    if (r.status != 201 && r.status != 200) {
        rc = r.status == 409 || r.status == 422 ? (report(&r), EXIT_JOB) : report(&r);
        free(r.body.data);
        return rc;
    }
    printf("%s\n", r.body.data ? r.body.data : "");
    json_t *j = strstr(query, "labels=") ? json_loads(r.body.data ? r.body.data : "", 0, NULL) : NULL;
    free(r.body.data);
    if (!j)
        return download_mesh(id, out);
    /* labels=all: each label's model's mesh to OUT-LABEL.EXT */
    json_t *models = json_object_get(j, "models"), *m;
    size_t k;
    json_array_foreach(models, k, m) {
        char path[4200];
        snprintf(path, sizeof path, "%.*s-%" JSON_INTEGER_FORMAT "%s", (int)(ext - out), out,
                 json_integer_value(json_object_get(m, "label")), ext);
        const char *mid = json_string_value(json_object_get(m, "id"));
        if (!rc && mid)
            rc = download_mesh(mid, path);
    }
    json_decref(j);
    return rc;
}

/* --since V taken out of argv (a mesh delta's version, not an option of the request): its value,
 * or NULL. */
static const char *take_since(int *argc, char **argv)
{
    for (int k = 0; k + 1 < *argc; k++)
        if (!strcmp(argv[k], "--since")) {
            const char *v = argv[k + 1];
            memmove(argv + k, argv + k + 2, (size_t)(*argc - k - 2) * sizeof *argv);
            *argc -= 2;
            return v;
        }
    return NULL;
}

/* An edit's or iso change's answer r: the model resource on stdout; then to OUT (when given) the
 * model's mesh, or with since its delta from that version (API.md's layout: a client holding
 * version since applies it by id). */
static int changed_model(struct response *r, const char *model, const char *out, const char *since)
{
    int rc = 0;
    if (r->status == 202 && (rc = job_answer(r))) /* longer than the sync wait (a hierarchy rebuilt from the store) */
        return rc;
    if (r->status != 200) {
        rc = r->status == 409 || r->status == 422 ? (report(r), r->job_id[0] ? EXIT_JOB : EXIT_REFUSED) : report(r);
        free(r->body.data);
        return rc;
    }
    printf("%s\n", r->body.data ? r->body.data : "");
    free(r->body.data);
    if (!out)
        return 0;
    if (!since)
        return download_mesh(model, out);
    char path[256];
    snprintf(path, sizeof path, "/models/%.64s/mesh?format=delta&since=%.20s", model, since);
    return get_file(path, out);
}

/* Whether OUT (NULL: none) is a mesh file edit and iso write, or any file for a delta (since). */
static bool mesh_out_ok(const char *out, const char *since)
{
    const char *ext = out ? strrchr(out, '.') : NULL;
    return !out || since || (ext && (!strcmp(ext, ".stl") || !strcmp(ext, ".ply") || !strcmp(ext, ".obj")));
}

/* POST /models/ID/edit?region=... with BLOCK's raw samples: the model resource after the edit on
 * stdout, and its mesh (or its delta since a version) written to OUT when -o is given. */
static int cmd_edit(int argc, char **argv)
{
    static const char *const OPTIONS[] = {"region", NULL};
    const char *model = NULL, *file = NULL, *out = NULL, *since = take_since(&argc, argv);
    char query[256] = "";
    if (argc < 1 || argv[0][0] == '-' || !read_args(argc - 1, argv + 1, OPTIONS, &file, &out, NULL, query, sizeof query))
        return usage();
    model = argv[0];
    if (!file || !query[0] || !mesh_out_ok(out, since))
        return usage();
    char route[128];
    snprintf(route, sizeof route, "/models/%.64s/edit", model);
    struct response r;
    int rc = post_file(route, query, file, "application/octet-stream", NULL, &r);
    return rc ? rc : changed_model(&r, model, out, since);
}

/* surfctl iso MODEL VALUE [-o OUT] [--since V]: POST /models/MODEL/iso?value=VALUE. */
static int cmd_iso(int argc, char **argv)
{
    const char *since = take_since(&argc, argv), *extra = NULL, *out = NULL;
    char none[8] = "";
    if (argc < 2 || argv[0][0] == '-' ||
        !read_args(argc - 2, argv + 2, (const char *const[]){NULL}, &extra, &out, NULL, none, sizeof none) || extra ||
        !mesh_out_ok(out, since))
        return usage();
    const char *model = argv[0], *value = argv[1]; /* (a value may be negative: -500) */
    char path[256];
    snprintf(path, sizeof path, "/models/%.64s/iso?value=%.40s", model, value);
    struct response r;
    int rc = request("POST", path, "", 0, NULL, NULL, &r);
    return rc ? rc : changed_model(&r, model, out, since);
}

static const char *const CONTOUR_OPTIONS[] = {"method", "caps", "roi", "parameterisation", NULL};

/* surfctl model / volume: POST /model or /volume as a job; the resource on stdout, the mesh of the
 * (first) model to -o OUT. */
static int cmd_contours(const char *route, int argc, char **argv)
{
    const char *file = NULL, *out = NULL;
    char query[600] = "";
    if (!read_args(argc, argv, CONTOUR_OPTIONS, &file, route[1] == 'm' ? &out : NULL, NULL, query, sizeof query) || !file)
        return usage();
    struct response r;
    int rc = run_job(route, query, file, type_of(file, route[1] == 'm' ? IN_MODEL : IN_VOLUME), &r);
    if (rc)
        return rc;
    char id[64] = "";
    json_t *j = json_loads(r.body.data ? r.body.data : "", 0, NULL);
    json_t *first = json_object_get(j, "models") ? json_array_get(json_object_get(j, "models"), 0) : j;
    const char *s = json_string_value(json_object_get(first, "id"));
    snprintf(id, sizeof id, "%s", s ? s : "");
    json_decref(j);
    printf("%s\n", r.body.data ? r.body.data : "");
    free(r.body.data);
    return out && id[0] ? download_mesh(id, out) : 0;
}

/* surfctl matrix: POST /matrix-model of a volume, or of a stored model (--model ID, no body). */
static int cmd_matrix(int argc, char **argv)
{
    static const char *const OPTIONS[] = {"iso", "dims", "type", "spacing", "origin", "model", "size", NULL};
    const char *file = NULL, *out = NULL;
    char query[600] = "";
    if (!read_args(argc, argv, OPTIONS, &file, &out, NULL, query, sizeof query) || !out ||
        (!file == !strstr(query, "model=")))
        return usage();
    struct response r;
    int rc = run_job("/matrix-model", query, file, file ? type_of(file, IN_ISOSURFACE) : NULL, &r);
    if (!rc)
        rc = write_file(out, &r.body);
    free(r.body.data);
    return rc;
}

/* surfctl mesh ID -o OUT [--format F] [--tolerance MM]. */
static int cmd_mesh(int argc, char **argv)
{
    static const char *const OPTIONS[] = {"format", "tolerance", "since", NULL};
    const char *id = NULL, *out = NULL;
    char query[256] = "";
    if (!read_args(argc, argv, OPTIONS, &id, &out, NULL, query, sizeof query) || !id || !out)
        return usage();
    char path[512];
    if (strstr(query, "format=")) /* --format given */
        snprintf(path, sizeof path, "/models/%.64s/mesh%s", id, query);
    else
        snprintf(path, sizeof path, "/models/%.64s/mesh%s%sformat=%s", id, query, query[0] ? "&" : "?", mesh_format_of(out));
    return get_file(path, out);
}

/* surfctl view ID -o OUT [render's options]: GET /models/ID/render. */
static int cmd_view(int argc, char **argv)
{
    const char *id = NULL, *out = NULL;
    char query[1024] = "";
    if (!read_args(argc, argv, RENDER_OPTIONS, &id, &out, NULL, query, sizeof query) || !id || !out)
        return usage();
    char path[1200];
    snprintf(path, sizeof path, "/models/%.64s/render%s", id, query);
    return get_file(path, out);
}

/* surfctl patches ID [-o OUT] and surfctl rtstruct ID -o OUT [--spacing MM]: a stored model's
 * output, following its job. */
static int cmd_model_output(const char *what, const char *const *options, bool need_out, int argc, char **argv)
{
    const char *id = NULL, *out = NULL;
    char query[256] = "", path[512];
    if (!read_args(argc, argv, options, &id, &out, NULL, query, sizeof query) || !id || (need_out && !out))
        return usage();
    snprintf(path, sizeof path, "/models/%.64s/%s%s", id, what, query);
    return get_file(path, out ? out : "-");
}

/* A request without a body whose answer's body goes to stdout; a job's (job: a 202 is a job still
 * running, not an answer such as a cancel's) followed to its end. */
static int simple_as(const char *method, const char *path, bool job)
{
    struct response r;
    int rc = request(method, path, NULL, 0, NULL, NULL, &r);
    if (!rc && r.status == 202 && job)
        rc = follow(r.job_id, "-");
    else if (!rc && r.status >= 300)
        rc = report(&r);
    else if (!rc && r.status != 204)
        printf("%s\n", r.body.data ? r.body.data : "");
    free(r.body.data);
    return rc;
}

static int simple(const char *method, const char *path) { return simple_as(method, path, false); }

/* Appends name=value to a query (URL-encoded) after sep ('?' or '&'): false when it does not fit. */
static bool query_add(char *q, size_t cap, const char *name, const char *value)
{
    char *enc = curl_easy_escape(NULL, value, 0);
    size_t at = strlen(q);
    int n = enc ? snprintf(q + at, cap - at, "%c%s=%s", strchr(q, '?') ? '&' : '?', name, enc) : -1;
    curl_free(enc);
    return n > 0 && (size_t)n < cap - at;
}

/* surfctl series, studies, pull and send: the DICOM network's routes (issue 44). */
static int cmd_dicom(const char *cmd, int argc, char **argv)
{
    char path[1024];
    if (!strcmp(cmd, "series")) {
        bool del = argc >= 1 && !strcmp(argv[argc - 1], "--delete");
        int n = argc - del;
        if (n > 1 || (del && n != 1))
            return usage();
        snprintf(path, sizeof path, "/series%s%.64s", n ? "/" : "", n ? argv[0] : "");
        return simple(del ? "DELETE" : "GET", path);
    }
    if (!strcmp(cmd, "studies")) {
        if (argc < 1)
            return usage();
        snprintf(path, sizeof path, "/pacs/%.31s/studies", argv[0]);
        for (int k = 1; k < argc; k++) {
            char *eq = strchr(argv[k], '=');
            if (!eq)
                return usage();
            *eq = 0;
            if (!query_add(path, sizeof path, argv[k], eq + 1))
                return usage();
        }
        return simple("GET", path);
    }
    if (!strcmp(cmd, "pull")) {
        if (argc < 2 || argc > 3)
            return usage();
        snprintf(path, sizeof path, "/series/pull");
        if (!query_add(path, sizeof path, "pacs", argv[0]) || !query_add(path, sizeof path, "study", argv[1]) ||
            (argc == 3 && !query_add(path, sizeof path, "series", argv[2])))
            return usage();
        return simple_as("POST", path, true);
    }
    /* send ID PACS [--as A] [--spacing MM] */
    if (argc < 2 || argc % 2)
        return usage();
    snprintf(path, sizeof path, "/models/%.64s/send", argv[0]);
    if (!query_add(path, sizeof path, "pacs", argv[1]))
        return usage();
    for (int k = 2; k + 1 < argc; k += 2)
        if ((strcmp(argv[k], "--as") && strcmp(argv[k], "--spacing")) ||
            !query_add(path, sizeof path, argv[k] + 2, argv[k + 1]))
            return usage();
    return simple_as("POST", path, true);
}

int main(int argc, char **argv)
{
    /* --progress=MODE and --cacert FILE anywhere, taken out before the command reads its arguments */
    int n = 0;
    cacert = getenv("SURFD_CACERT") && *getenv("SURFD_CACERT") ? getenv("SURFD_CACERT") : NULL;
    for (int k = 0; k < argc; k++) {
        if (!strcmp(argv[k], "--cacert") && k + 1 < argc) {
            cacert = argv[++k];
            continue;
        }
        if (!strncmp(argv[k], "--progress=", 11)) {
            const char *m = argv[k] + 11;
            progress_mode = !strcmp(m, "bar") ? PROGRESS_BAR : !strcmp(m, "plain") ? PROGRESS_PLAIN
                            : !strcmp(m, "none")                                    ? PROGRESS_NONE
                                                                                    : (enum progress_mode)-1;
            if ((int)progress_mode < 0)
                return usage();
            continue;
        }
        argv[n++] = argv[k];
    }
    argc = n;
    if (argc < 2)
        return usage();
    const char *cmd = argv[1];
    if (!strcmp(cmd, "--help") || !strcmp(cmd, "-h") || !strcmp(cmd, "help")) {
        usage_to(stdout, argc > 2 ? argv[2] : NULL);
        return 0;
    }
    for (int k = 2; k < argc; k++)
        if (!strcmp(argv[k], "--help") || !strcmp(argv[k], "-h")) {
            bool known = false;
            for (size_t u = 0; u < N_USAGE; u++)
                known |= !strcmp(USAGE[u][0], cmd);
            usage_to(stdout, known ? cmd : NULL);
            return known ? 0 : EXIT_USAGE;
        }
    current_cmd = cmd;
    curl_global_init(CURL_GLOBAL_DEFAULT);
    int rc;
    char path[160];
    bool one = argc == 3 && argv[2][0] != '-'; /* a command of one ID */
    if (!strcmp(cmd, "render")) {
        rc = cmd_render(argc - 2, argv + 2);
    } else if (!strcmp(cmd, "model") || !strcmp(cmd, "volume")) {
        rc = cmd_contours(cmd[0] == 'm' ? "/model" : "/volume", argc - 2, argv + 2);
    } else if (!strcmp(cmd, "isosurface")) {
        rc = cmd_isosurface(argc - 2, argv + 2);
    } else if (!strcmp(cmd, "edit")) {
        rc = cmd_edit(argc - 2, argv + 2);
    } else if (!strcmp(cmd, "iso")) {
        rc = cmd_iso(argc - 2, argv + 2);
    } else if (!strcmp(cmd, "matrix")) {
        rc = cmd_matrix(argc - 2, argv + 2);
    } else if (!strcmp(cmd, "mesh")) {
        rc = cmd_mesh(argc - 2, argv + 2);
    } else if (!strcmp(cmd, "view")) {
        rc = cmd_view(argc - 2, argv + 2);
    } else if (!strcmp(cmd, "patches")) {
        static const char *const NONE[] = {NULL};
        rc = cmd_model_output("patches", NONE, false, argc - 2, argv + 2);
    } else if (!strcmp(cmd, "rtstruct")) {
        static const char *const SPACING[] = {"spacing", "format", NULL};
        rc = cmd_model_output("rtstruct", SPACING, true, argc - 2, argv + 2);
    } else if (!strcmp(cmd, "series") || !strcmp(cmd, "studies") || !strcmp(cmd, "pull") || !strcmp(cmd, "send")) {
        rc = cmd_dicom(cmd, argc - 2, argv + 2);
    } else if (!strcmp(cmd, "models") && (argc == 2 || one)) {
        snprintf(path, sizeof path, "/models%s%.64s", one ? "/" : "", one ? argv[2] : "");
        rc = simple("GET", path);
    } else if (!strcmp(cmd, "delete") && one) {
        snprintf(path, sizeof path, "/models/%.64s", argv[2]);
        rc = simple("DELETE", path);
        if (!rc)
            fprintf(stderr, "surfctl: model %s deleted\n", argv[2]);
    } else if (!strcmp(cmd, "jobs") && (argc == 2 || (argc == 4 && !strcmp(argv[2], "--state")))) {
        snprintf(path, sizeof path, "/jobs%s%.32s", argc == 4 ? "?state=" : "", argc == 4 ? argv[3] : "");
        rc = simple("GET", path);
    } else if ((!strcmp(cmd, "job") || !strcmp(cmd, "cancel")) && one) {
        snprintf(path, sizeof path, "/jobs/%.64s%s", argv[2], cmd[0] == 'c' ? "/cancel" : "");
        rc = simple(cmd[0] == 'c' ? "POST" : "GET", path);
    } else if (!strcmp(cmd, "wait") && argc >= 3) {
        char state[32];
        rc = wait_job(argv[2], state, sizeof state);
        if (!rc && strcmp(state, "succeeded"))
            rc = EXIT_JOB;
        if (!rc && argc == 5 && !strcmp(argv[3], "-o"))
            rc = fetch_result(argv[2], argv[4]);
    } else if (!strcmp(cmd, "result") && argc == 5 && !strcmp(argv[3], "-o")) {
        rc = fetch_result(argv[2], argv[4]);
    } else {
        current_cmd = NULL;
        rc = usage();
    }
    curl_global_cleanup();
    return rc;
}
