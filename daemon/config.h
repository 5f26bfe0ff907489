/* config.h - surfd serve's settings: one declarative table (name, type, bounds, default, field)
 * read from a config file ("key = value" lines, # comments) and then from --key value flags, so
 * flags win. deploy/surfd.conf documents every key. */
#ifndef SURFD_CONFIG_H
#define SURFD_CONFIG_H

#include <stdbool.h>
#include <stddef.h>
#include <stdio.h>

#include "../core/base/err.h"

struct config {
    char listen[128];       /* HOST:PORT */
    char data_dir[512];
    char store[512];        /* "" (SQLite in data_dir) or a postgresql:// URI */
    char node_name[64];     /* "" : host name and port */
    long lease;             /* seconds a claim lasts without a heartbeat */
    long max_attempts;      /* claims of a job before it fails */
    long threads;           /* workers; 0: all cores */
    long queue_max;         /* jobs waiting before 429 */
    long max_body;          /* bytes of request body */
    long max_volume;        /* bytes of a streamed volume (POST /isosurface) */
    long upload_share;      /* bytes of the data dir one owner's uploads may hold (shares.h) */
    long edit_memory;       /* bytes of the hierarchies kept for edits (daemon/job_edit.c) */
    long journal_kept;      /* versions of a model's mesh changes kept for deltas (daemon/job_edit.c) */
    long max_triangles;     /* of one isosurface (job_iso_opts) */
    long max_triangles_per_byte; /* ... for each byte of its request (job_iso.c) */
    long max_labels;        /* labels of one map ?labels=all makes models of (job_iso.c) */
    long store_piece;       /* bytes of a stored value kept in one piece at most (store.h) */
    long job_memory;        /* bytes one job may allocate (jobq.h); 0 in the file: a share (cmd_serve.c) */
    long mesh_cache;        /* bytes of cached meshes in the store (0: none) */
    long frame_cache;       /* bytes of models' prepared hierarchies kept in memory (daemon/frames.c) */
    long sync_wait;         /* seconds a request waits for its job before 202 */
    char token_file[512];
    char tls_cert[512];
    char tls_key[512];
    char log_level[16];     /* error, warn, info, debug */
    bool insecure_no_auth;  /* allow a non-loopback listener without tokens */
    bool keep_phi;          /* keep DICOM uploads' identifying elements (job_iso.c blanks them) */
    char cors_origins[1024]; /* origins allowed to call from a page, space-separated ("*": any); "": CORS off */
    long result_ttl;        /* seconds finished jobs are kept */
    long result_max;        /* finished jobs kept at most */
    long drain_timeout;     /* seconds SIGTERM waits for running jobs */
    long max_connections;
    long per_ip_connections;
    long connection_timeout; /* seconds an idle connection is kept (also between kept-alive requests) */
    long header_timeout;    /* seconds a connection has to send its request's headers */
    long body_timeout;      /* seconds a request has to send its body */
    /* the DICOM node (dicom_node.h) */
    long dicom_listen;      /* port of the storage SCP; 0: none */
    char ae_title[17];
    char dicom_peers[512];  /* file of the peers allowed: AE title, host, port a line */
    long series_idle;       /* seconds without an instance before a series counts as complete */
    bool auto_model;        /* a received RT Structure Set becomes models when complete */
    char pacs[2048];        /* NAME=URL or NAME=dicom://AET@HOST:PORT, space-separated (pacs.h) */
    char pacs_credentials[2048]; /* NAME=FILE, space-separated */
    char pacs_cacert[512];  /* the CA bundle https PACS are checked against ("": the system's) */
};

void config_defaults(struct config *c);
/* Applies argv (after "serve"); --config F is read first wherever it stands. 0, or SF_EINVAL (a
 * setting or argument) or SF_EIO (the file) with err's message. */
int config_load(struct config *c, int argc, char **argv, struct sf_err *err);
/* The usage text, generated from the table. */
void config_usage(FILE *f);

#endif
