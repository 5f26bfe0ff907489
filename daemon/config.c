/* config.c - the settings table (as Redis's config.c: name, bounds, default, field) and the two
 * readers, file and flags, that both go through config_set(). */
#include "config.h"

#include <ctype.h>
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../api/volume_io.h" /* VOLUME_MAX_LABELS */

enum ctype { C_STR, C_LIST, C_LONG, C_BOOL }; /* C_LIST: a string each use appends to, space-separated */

struct setting {
    const char *name;
    enum ctype type;
    size_t offset;
    size_t size;       /* C_STR: buffer size */
    long lo, hi;       /* C_LONG bounds */
    const char *dflt;
    const char *help;
};

#define S(name, field, dflt, help) {name, C_STR, offsetof(struct config, field), sizeof(((struct config *)0)->field), 0, 0, dflt, help}
#define LIST(name, field, help) {name, C_LIST, offsetof(struct config, field), sizeof(((struct config *)0)->field), 0, 0, "", help}
#define L(name, field, lo, hi, dflt, help) {name, C_LONG, offsetof(struct config, field), 0, lo, hi, dflt, help}
#define B(name, field, dflt, help) {name, C_BOOL, offsetof(struct config, field), 0, 0, 0, dflt, help}

static const struct setting SETTINGS[] = {
    S("listen", listen, "127.0.0.1:8080", "HOST:PORT to listen on"),
    S("data-dir", data_dir, "./var", "directory of the embedded store (and local scratch)"),
    S("store", store, "", "where jobs live: empty for the embedded store in data-dir, or a postgresql:// URI shared by several nodes"),
    S("node-name", node_name, "", "this node's name in the shared store (default: host name and port)"),
    L("lease", lease, 2, 3600, "30", "seconds a node's claim on a running job lasts without a heartbeat"),
    L("max-attempts", max_attempts, 1, 100, "2", "claims of a job (crashes, lost nodes) before it fails"),
    L("threads", threads, 0, 1024, "0", "worker threads (0: all cores)"),
    L("queue-max", queue_max, 1, 1000000, "64", "jobs waiting before requests get 429"),
    L("max-body", max_body, 1024, 1L << 30, "67108864", "largest request body in bytes (413 above)"),
    L("max-volume", max_volume, 1024, 1L << 40, "4294967296", "largest volume POST /isosurface takes, in bytes: streamed to the data dir as it arrives, never held in memory"),
    L("upload-share", upload_share, 0, 1L << 50, "0", "bytes of the data dir one owner's uploads may hold: the streamed bodies arriving and those kept for its jobs not yet ended; an upload that would go over is refused from its headers with 429, or 413 when it alone is larger (0: a quarter of the data dir's file system)"),
    L("journal-kept", journal_kept, 1, 1L << 20, "64", "versions of a model's mesh changes kept for GET /models/{id}/mesh?format=delta&since=V (older: 410); the journal is compacted every journal-kept / 2 versions"),
    L("edit-memory", edit_memory, 0, 1L << 40, "1073741824", "bytes of memory kept for edits of isosurface models (the hierarchies of the models edited last; 0: rebuilt for every edit)"),
    L("max-triangles", max_triangles, 1000, 2000000000, "40000000", "triangles of one isosurface, or of the stored meshes one scene names, at most: more fails the job with a 422 before its mesh is allocated (a mesh costs some 80 bytes a triangle from extraction to the store)"),
    L("max-triangles-per-byte", max_triangles_per_byte, 0, 1000000000, "64", "triangles an isosurface may have for each byte of its request (a volume's file, an FRep's JSON), 4 M at least: more fails the job with a 422 from its count pass, so that a few kilobytes of a compressed field with surface in every cell cannot make a mesh of gigabytes (gzip scans make under 1 a byte, gzip label maps 3 to 5; 0: no such limit)"),
    L("max-labels", max_labels, 1, VOLUME_MAX_LABELS, "256", "labels of one map POST /isosurface?labels=all makes models of, at most (one model each): a map with more is refused with a 422 at ?labels, from its header when it names them (3D Slicer's segments), else once its samples are read, before any surface is made"),
    L("store-piece", store_piece, 65536, 512L << 20, "268435456", "bytes of a stored value (a mesh, a volume kept for edits, a result) kept in one row at most: a longer one is kept as several (SQLite and PostgreSQL hold at most 1 GB in one value)"),
    L("job-memory", job_memory, 0, 1L << 50, "0", "bytes of memory one job may allocate: more fails it alone with a 422, and an isosurface whose mesh would take more (some 80 bytes a triangle) is refused before it is made (0: three quarters of the memory the process may use, the machine's or less under a cgroup's memory.max or RLIMIT_AS, shared among the workers)"),
    L("mesh-cache", mesh_cache, 0, 1L << 40, "536870912", "bytes of the store kept for models' meshes, each computed once per format and tolerance (the least recently used dropped beyond; 0: none kept)"),
    L("frame-cache", frame_cache, 0, 1L << 40, "536870912", "bytes of memory kept for stored models' prepared hierarchies, so a repeat view of a model prepares only its camera (the least recently used dropped beyond; 0: none kept)"),
    L("sync-wait", sync_wait, 0, 3600, "60", "seconds a request waits for its job before 202"),
    S("token-file", token_file, "", "file of bearer tokens, one per line"),
    S("tls-cert", tls_cert, "", "PEM certificate for native TLS"),
    S("tls-key", tls_key, "", "PEM private key for native TLS"),
    S("log-level", log_level, "info", "error, warn, info or debug"),
    B("insecure-no-auth", insecure_no_auth, "false", "allow a non-loopback listener without tokens"),
    B("keep-phi", keep_phi, "false", "keep the elements of uploaded DICOM series that identify the patient (names, IDs, dates, institutions, private elements: PS3.15's basic profile); by default they are blanked before the upload is stored"),
    LIST("cors-origin", cors_origins, "an origin (https://portal.example) whose pages may call surfd (CORS; repeatable; * for any; off when none)"),
    L("result-ttl", result_ttl, 1, 365L * 86400, "86400", "seconds finished jobs and results are kept"),
    L("result-max", result_max, 1, 10000000, "10000", "finished jobs kept at most"),
    L("drain-timeout", drain_timeout, 0, 3600, "30", "seconds SIGTERM waits for running jobs"),
    L("max-connections", max_connections, 4, 100000, "256", "simultaneous connections"),
    L("per-ip-connections", per_ip_connections, 1, 100000, "64", "simultaneous connections per client address"),
    L("connection-timeout", connection_timeout, 1, 3600, "30", "seconds an idle connection is kept"),
    L("header-timeout", header_timeout, 1, 3600, "10", "seconds a new connection has to send its request's headers"),
    L("body-timeout", body_timeout, 1, 86400, "300", "seconds a request has to send its body"),
    L("dicom-listen", dicom_listen, 0, 65535, "0", "port of surfd's DICOM node (C-ECHO, C-STORE: instances kept by series in the store; 0: no node)"),
    S("ae-title", ae_title, "SURFD", "the DICOM node's AE title: associations calling another are refused; surfd calls a PACS by it"),
    S("dicom-peers", dicom_peers, "", "file of the DICOM peers allowed to associate and to be sent to, a line each: AE_TITLE HOST PORT (# comments); others are refused at association"),
    L("series-idle", series_idle, 1, 86400, "30", "seconds without a new instance of a received series before it counts as complete"),
    LIST("pacs", pacs, "a PACS to pull from and send to, NAME=URL (a DICOMweb root, http or https) or NAME=dicom://AET@HOST:PORT (DIMSE: sent to by C-STORE); repeatable"),
    LIST("pacs-credentials", pacs_credentials, "NAME=FILE: the file (mode 0600) holding user:password for the DICOMweb PACS NAME (HTTP basic auth); repeatable"),
    S("pacs-cacert", pacs_cacert, "", "CA bundle https PACS are checked against (default: the system's)"),
    B("auto-model", auto_model, "true", "a received RT Structure Set becomes models (one per ROI with contours, as POST /model makes them) once its series is complete"),
};
#define N_SETTINGS (sizeof SETTINGS / sizeof *SETTINGS)

static int config_set(struct config *c, const char *name, const char *value, struct sf_err *err)
{
    for (size_t k = 0; k < N_SETTINGS; k++) {
        const struct setting *s = &SETTINGS[k];
        if (strcmp(s->name, name))
            continue;
        void *field = (char *)c + s->offset;
        if (s->type == C_STR) {
            if (strlen(value) >= s->size) {
                return sf_fail(err, SF_EINVAL, "", "%s: value longer than %zu characters", name, s->size - 1);
            }
            strcpy(field, value);
        } else if (s->type == C_LIST) {
            size_t used = strlen(field);
            if (strpbrk(value, " \t,")) {
                return sf_fail(err, SF_EINVAL, "", "%s: one value a use, without spaces or commas: \"%s\"", name,
                               value);
            }
            if (used + 1 + strlen(value) >= s->size) {
                return sf_fail(err, SF_EINVAL, "", "%s: the values are longer than %zu characters in all", name,
                               s->size - 1);
            }
            if (*value)
                snprintf((char *)field + used, s->size - used, "%s%s", used ? " " : "", value);
        } else if (s->type == C_LONG) {
            char *end;
            errno = 0;
            long v = strtol(value, &end, 10);
            if (errno || end == value || *end || v < s->lo || v > s->hi) {
                return sf_fail(err, SF_EINVAL, "", "%s: expected an integer in %ld..%ld, got \"%s\"", name, s->lo,
                               s->hi, value);
            }
            *(long *)field = v;
        } else {
            if (!strcmp(value, "true") || !strcmp(value, "1") || !strcmp(value, "yes"))
                *(bool *)field = true;
            else if (!strcmp(value, "false") || !strcmp(value, "0") || !strcmp(value, "no"))
                *(bool *)field = false;
            else {
                return sf_fail(err, SF_EINVAL, "", "%s: expected true or false, got \"%s\"", name, value);
            }
        }
        return 0;
    }
    return sf_fail(err, SF_EINVAL, "", "unknown setting \"%s\"", name);
}

void config_defaults(struct config *c)
{
    memset(c, 0, sizeof *c);
    for (size_t k = 0; k < N_SETTINGS; k++)
        config_set(c, SETTINGS[k].name, SETTINGS[k].dflt, NULL);
}

static char *trim(char *s)
{
    while (isspace((unsigned char)*s))
        s++;
    char *e = s + strlen(s);
    while (e > s && isspace((unsigned char)e[-1]))
        *--e = 0;
    return s;
}

static int load_file(struct config *c, const char *path, struct sf_err *err)
{
    FILE *f = fopen(path, "r");
    if (!f)
        return sf_fail(err, SF_EIO, "", "%s: %s", path, strerror(errno));
    char line[1024];
    int n = 0, rc = 0;
    while (!rc && fgets(line, sizeof line, f)) {
        n++;
        char *hash = strchr(line, '#');
        if (hash)
            *hash = 0;
        char *s = trim(line);
        if (!*s)
            continue;
        char *eq = strchr(s, '=');
        if (!eq) {
            rc = sf_fail(err, SF_EINVAL, "", "%s:%d: expected \"key = value\"", path, n);
            break;
        }
        *eq = 0;
        struct sf_err inner = {0};
        if ((rc = config_set(c, trim(s), trim(eq + 1), &inner)))
            sf_fail(err, rc, "", "%s:%d: %s", path, n, inner.message);
    }
    fclose(f);
    return rc;
}

int config_load(struct config *c, int argc, char **argv, struct sf_err *err)
{
    for (int k = 1; k + 1 < argc; k++) {
        int rc = strcmp(argv[k], "--config") ? 0 : load_file(c, argv[k + 1], err);
        if (rc)
            return rc;
    }
    for (int k = 1; k < argc; k++) {
        const char *a = argv[k];
        if (strncmp(a, "--", 2))
            return sf_fail(err, SF_EINVAL, "", "unexpected argument \"%s\"", a);
        if (!strcmp(a, "--config")) {
            k++;
            continue;
        }
        /* booleans may stand alone: --insecure-no-auth */
        bool is_bool = false;
        for (size_t s = 0; s < N_SETTINGS; s++)
            is_bool |= !strcmp(SETTINGS[s].name, a + 2) && SETTINGS[s].type == C_BOOL;
        const char *value = is_bool && (k + 1 >= argc || !strncmp(argv[k + 1], "--", 2)) ? "true" : NULL;
        if (!value) {
            if (k + 1 >= argc)
                return sf_fail(err, SF_EINVAL, "", "%s needs a value", a);
            value = argv[++k];
        }
        int rc = config_set(c, a + 2, value, err);
        if (rc)
            return rc;
    }
    return 0;
}

void config_usage(FILE *f)
{
    fprintf(f, "usage: surfd serve [--config FILE] [--SETTING VALUE]...\n\nsettings (also as \"key = value\" in FILE):\n");
    for (size_t k = 0; k < N_SETTINGS; k++)
        fprintf(f, "  --%-20s %s (default: %s)\n", SETTINGS[k].name, SETTINGS[k].help,
                SETTINGS[k].dflt[0] ? SETTINGS[k].dflt : "none");
}
