/* surfctl.c - the command-line client of surfd: speaks only HTTP (libcurl), reads SURFD_URL
 * (default http://127.0.0.1:8080) and SURFD_TOKEN from the environment.
 *
 *   surfctl render FILE -o OUT [--async] [--method M] [--width W] [--height H] [--output FMT]
 *   surfctl isosurface VOLUME --iso V -o OUT.stl [...]
 *   surfctl edit MODEL BLOCK --region X0,Y0,Z0,NX,NY,NZ [-o OUT.stl]
 *   surfctl jobs [--state S]          surfctl job ID
 *   surfctl wait ID [-o OUT]          (progress bar on stderr)
 *   surfctl result ID -o OUT          surfctl cancel ID
 *
 * Exit codes: 0 done; 1 the job failed or was cancelled; 2 usage; 3 surfd unreachable;
 * 4 request refused (4xx: the problem's detail and pointer go to stderr); 5 server error (5xx). */
#include <curl/curl.h>
#include <jansson.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <time.h>
#include <unistd.h>

enum { EXIT_JOB = 1, EXIT_USAGE = 2, EXIT_UNREACHABLE = 3, EXIT_REFUSED = 4, EXIT_SERVER = 5 };

#define MAX_RESPONSE (1L << 30) /* a result larger than 1 GiB is refused */

struct buf {
    char *data;
    size_t len;
};

static size_t on_data(char *p, size_t size, size_t n, void *arg)
{
    struct buf *b = arg;
    size_t add = size * n;
    if (b->len + add > (size_t)MAX_RESPONSE)
        return 0;
    char *d = realloc(b->data, b->len + add + 1);
    if (!d)
        return 0;
    memcpy(d + b->len, p, add);
    b->data = d;
    b->len += add;
    b->data[b->len] = 0;
    return add;
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

/* A file's media type by its extension, from a {".ext", "type"} table ending in {NULL, fallback}. */
static const char *type_of(const char *path, const char *const (*table)[2])
{
    const char *dot = strrchr(path, '.');
    int k = 0;
    while (table[k][0] && !(dot && !strcmp(dot, table[k][0])))
        k++;
    return table[k][1];
}

static const char *const SCENE_TYPES[][2] = {{".bpt", "model/x-bpt"}, {".nurbs", "model/vrml"}, {".wrl", "model/vrml"},
                                             {".json", "application/json"}, {NULL, "text/plain"}};
static const char *const VOLUME_TYPES[][2] = {{".nrrd", "application/x-nrrd"}, {".mha", "application/x-metaimage"},
                                              {".json", "application/json"}, {NULL, "application/octet-stream"}};

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

/* Polls the job until it ends, with a progress bar on stderr when it is a terminal. */
static int wait_job(const char *id, char *state, size_t state_len)
{
    char path[128];
    snprintf(path, sizeof path, "/jobs/%s", id);
    bool tty = isatty(2);
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
        json_decref(j);
        free(r.body.data);
        bool done = strcmp(state, "queued") && strcmp(state, "running");
        if (tty) {
            int w = (int)(progress * 40 + 0.5);
            fprintf(stderr, "\r%s [%.*s%*s] %3.0f%% %-9s", id, w, "########################################", 40 - w,
                    "", progress * 100, state);
            if (done)
                fputc('\n', stderr);
        }
        if (done)
            return 0;
        struct timespec ts = {0, 200 * 1000000L};
        nanosleep(&ts, NULL);
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
            snprintf(query + n, cap - n, "%c%s=%s", n ? '&' : '?', names[k], v);
            return true;
        }
    return false;
}

/* A job still running when its request answered 202: followed to its end, its result to out. */
static int follow(const char *id, const char *out)
{
    char state[32];
    int rc = wait_job(id, state, sizeof state);
    if (!rc && strcmp(state, "succeeded")) {
        fprintf(stderr, "surfctl: job %s %s\n", id, state);
        rc = EXIT_JOB;
    }
    return rc ? rc : fetch_result(id, out);
}

static int usage(void)
{
    fprintf(stderr, "usage: surfctl render FILE -o OUT [--async] [--method M] [--width W] [--height H] [--output png|exr|tiff]\n"
                    "       surfctl isosurface VOLUME --iso V -o OUT.stl|.ply|.obj [--dims X,Y,Z --type T --spacing S --origin O]\n"
                    "                          [--levels 1-4 [--max-error MM]] [--features none|sharp] [--closed true|false] [--name N]\n"
                    "                          (VOLUME: .nrrd, .mha, raw samples, or an FRep object as .json)\n"
                    "       surfctl edit MODEL BLOCK --region X0,Y0,Z0,NX,NY,NZ [-o OUT.stl|.ply|.obj]\n"
                    "                          (BLOCK: the region's raw samples in the model's sample type)\n"
                    "       surfctl jobs [--state S] | job ID | wait ID [-o OUT] | result ID -o OUT | cancel ID\n"
                    "environment: SURFD_URL (default http://127.0.0.1:8080), SURFD_TOKEN\n");
    return EXIT_USAGE;
}

/* A command's FILE, -o OUT, --async (when async is not NULL) and the query options of names:
 * false on anything else. */
static bool read_args(int argc, char **argv, const char *const *names, const char **file, const char **out,
                      bool *async, char *query, size_t cap)
{
    for (int k = 0; k < argc; k++) {
        const char *a = argv[k], *v = k + 1 < argc ? argv[k + 1] : NULL;
        if (!strcmp(a, "-o") && v)
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

static int cmd_render(int argc, char **argv)
{
    static const char *const OPTIONS[] = {"method", "width", "height", "output", "format", "azimuth", "elevation", NULL};
    const char *file = NULL, *out = NULL;
    char query[512] = "";
    bool async = false;
    if (!read_args(argc, argv, OPTIONS, &file, &out, &async, query, sizeof query) || !file || (!out && !async))
        return usage();
    struct response r;
    int rc = post_file("/render", query, file, type_of(file, SCENE_TYPES), async ? "respond-async" : NULL, &r);
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
    snprintf(path, sizeof path, "/jobs/%s/result", id);
    return request("GET", path, NULL, 0, NULL, NULL, r);
}

/* Model id's mesh to out (its format from the extension), following the mesh job when it is long. */
static int download_mesh(const char *id, const char *out)
{
    char path[160];
    struct response r;
    snprintf(path, sizeof path, "/models/%.64s/mesh?format=%s", id, strrchr(out, '.') + 1);
    int rc = request("GET", path, NULL, 0, NULL, NULL, &r);
    if (rc)
        return rc;
    if (r.status == 202) /* a mesh job longer than the server's sync wait: follow it too */
        rc = follow(r.job_id, out);
    else
        rc = r.status == 200 ? write_file(out, &r.body) : report(&r);
    free(r.body.data);
    return rc;
}

/* POST /isosurface, the job followed with the progress bar, the model resource on stdout and
 * its mesh written to OUT (format from its extension). */
static int cmd_isosurface(int argc, char **argv)
{
    static const char *const OPTIONS[] = {"iso", "dims", "type", "spacing", "origin", "closed", "name", "levels",
                                          "max_error", "features", NULL};
    const char *file = NULL, *out = NULL;
    char query[600] = "";
    if (!read_args(argc, argv, OPTIONS, &file, &out, NULL, query, sizeof query))
        return usage();
    const char *ext = out ? strrchr(out, '.') : NULL;
    if (!file || !ext || (strcmp(ext, ".stl") && strcmp(ext, ".ply") && strcmp(ext, ".obj")))
        return usage();
    struct response r;
    int rc = post_file("/isosurface", query, file, type_of(file, VOLUME_TYPES), "respond-async", &r);
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
    free(r.body.data);
    return download_mesh(id, out);
}

/* POST /models/ID/edit?region=... with BLOCK's raw samples: the model resource after the edit on
 * stdout, and its mesh written to OUT when -o is given. */
static int cmd_edit(int argc, char **argv)
{
    static const char *const OPTIONS[] = {"region", NULL};
    const char *model = NULL, *file = NULL, *out = NULL;
    char query[256] = "";
    if (argc < 1 || argv[0][0] == '-' || !read_args(argc - 1, argv + 1, OPTIONS, &file, &out, NULL, query, sizeof query))
        return usage();
    model = argv[0];
    const char *ext = out ? strrchr(out, '.') : NULL;
    if (!file || !query[0] || (out && (!ext || (strcmp(ext, ".stl") && strcmp(ext, ".ply") && strcmp(ext, ".obj")))))
        return usage();
    char route[128];
    snprintf(route, sizeof route, "/models/%.64s/edit", model);
    struct response r;
    int rc = post_file(route, query, file, "application/octet-stream", NULL, &r);
    if (rc)
        return rc;
    if (r.status == 202 && (rc = job_answer(&r))) /* longer than the sync wait (a hierarchy rebuilt from the store) */
        return rc;
    if (r.status != 200) {
        rc = r.status == 409 || r.status == 422 ? (report(&r), r.job_id[0] ? EXIT_JOB : EXIT_REFUSED) : report(&r);
        free(r.body.data);
        return rc;
    }
    printf("%s\n", r.body.data ? r.body.data : "");
    free(r.body.data);
    return out ? download_mesh(model, out) : 0;
}

int main(int argc, char **argv)
{
    if (argc < 2)
        return usage();
    curl_global_init(CURL_GLOBAL_DEFAULT);
    const char *cmd = argv[1];
    int rc;
    if (!strcmp(cmd, "render")) {
        rc = cmd_render(argc - 2, argv + 2);
    } else if (!strcmp(cmd, "isosurface")) {
        rc = cmd_isosurface(argc - 2, argv + 2);
    } else if (!strcmp(cmd, "edit")) {
        rc = cmd_edit(argc - 2, argv + 2);
    } else if (!strcmp(cmd, "jobs") || !strcmp(cmd, "job") || !strcmp(cmd, "cancel")) {
        char path[128];
        if (!strcmp(cmd, "jobs"))
            snprintf(path, sizeof path, "/jobs%s%s", argc >= 4 && !strcmp(argv[2], "--state") ? "?state=" : "",
                     argc >= 4 && !strcmp(argv[2], "--state") ? argv[3] : "");
        else if (argc == 3)
            snprintf(path, sizeof path, "/jobs/%.64s%s", argv[2], !strcmp(cmd, "cancel") ? "/cancel" : "");
        else
            return usage();
        struct response r;
        rc = request(!strcmp(cmd, "cancel") ? "POST" : "GET", path, NULL, 0, NULL, NULL, &r);
        if (!rc)
            rc = r.status < 300 ? (printf("%s\n", r.body.data ? r.body.data : ""), 0) : report(&r);
        free(r.body.data);
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
        rc = usage();
    }
    curl_global_cleanup();
    return rc;
}
