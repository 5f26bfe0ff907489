/* dicomweb.h - a DICOMweb client (DICOM PS3.18) for the PACS surfd pulls from and sends to:
 * QIDO-RS searches (the PACS's JSON answered as it is), WADO-RS retrieval of a series into files,
 * one an instance, as it streams in, and STOW-RS of files with each instance's status. On libcurl.
 *
 * Hand-written because Debian has no C DICOMweb library: DCMTK speaks DIMSE (and WADO-URI)
 * only, and Orthanc's client is C++ inside its plugin. It talks to the network and writes files,
 * so it is daemon/ code, called from a job's worker, never from the HTTP server's threads. It never
 * logs and its messages never hold a query's values, a response body or a credential: a query
 * names patients (PatientID=...), and a PACS's error page may echo it. A PACS that is down fails
 * after DICOMWEB_ATTEMPTS attempts with bounded timeouts, never hangs. */
#ifndef SURFD_DICOMWEB_H
#define SURFD_DICOMWEB_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "../core/base/err.h"

/* The defaults of struct dicomweb_config, each what it bounds. */
#define DICOMWEB_CONNECT_TIMEOUT_S 5    /* a TCP (and TLS) connection: a PACS on the LAN answers in ms */
#define DICOMWEB_STALL_TIMEOUT_S 30     /* no byte either way for this long: the PACS has stopped */
#define DICOMWEB_REQUEST_TIMEOUT_S 600  /* one request whole: a 1 000-instance series at 10 MB/s fits */
#define DICOMWEB_ATTEMPTS 3             /* tries of a request that failed before its answer began */
#define DICOMWEB_RETRY_DELAY_MS 500     /* before the 2nd try; doubled before each next one */
#define DICOMWEB_MAX_ANSWER (16u << 20) /* a QIDO or STOW answer's JSON (a study's series: some KB) */
#define DICOMWEB_MAX_INSTANCES 100000   /* instances one retrieve writes (a series has some thousands) */

struct dicomweb_config {
    const char *url;              /* the DICOMweb root, http or https ("https://pacs/dicom-web");
                                   * no user:password@ in it: credentials come from a file */
    const char *credentials_file; /* NULL: none; else its first line is "user:password" (HTTP basic
                                   * auth); refused when group-writable or readable by others */
    const char *ca_file;          /* NULL: the system's CAs, for https */
    int connect_timeout_s;        /* 0: DICOMWEB_CONNECT_TIMEOUT_S */
    int stall_timeout_s;          /* 0: DICOMWEB_STALL_TIMEOUT_S */
    int request_timeout_s;        /* 0: DICOMWEB_REQUEST_TIMEOUT_S */
    int attempts;                 /* 0: DICOMWEB_ATTEMPTS; 1: no retry */
};

/* A PACS's settings, checked and its credentials read. Read-only once made: several threads may
 * use one at once (each call has its own connection). */
struct dicomweb;

/* Calls curl_global_init: once, in main, before any thread starts. 0 or SF_EBACKEND. */
int dicomweb_global_init(void);
/* A PACS from cfg (copied; cfg and its strings may go once it returns). Caller frees with
 * dicomweb_free(). 0, SF_EINVAL (the URL, the credentials file's mode or content), SF_EIO (the
 * file cannot be read), SF_ENOMEM. */
int dicomweb_open(const struct dicomweb_config *cfg, struct dicomweb **out, struct sf_err *err);
void dicomweb_free(struct dicomweb *dw); /* the credentials wiped; NULL: nothing */

/* QIDO-RS. What is searched: studies, series (of study_uid, or all when it is NULL), instances
 * (of series_uid of study_uid; either may be NULL for a wider search). */
enum dicomweb_level { DICOMWEB_STUDIES, DICOMWEB_SERIES, DICOMWEB_INSTANCES };
struct dicomweb_param {
    const char *name;  /* an attribute's keyword or tag ("PatientID", "0020000D"), or a QIDO key
                        * ("limit", "offset", "includefield", "fuzzymatching") */
    const char *value; /* as the user wrote it, unencoded ("19*", "20240101-20241231") */
};
/* GET {url}/studies[...]?name=value&... (each name and value percent-encoded); *json: the PACS's
 * answer, a DICOM JSON array (PS3.18 F.2), as it sent it, NUL-terminated, "[]" for 204 No
 * Content; caller frees with free(). 0; SF_EINVAL (a UID that is not one; the PACS answered 400);
 * SF_ENOTFOUND (404); SF_ELIMIT (over DICOMWEB_MAX_ANSWER); SF_EFORMAT (not a JSON array); SF_EIO
 * (unreachable, timed out, refused the credentials, any other status); SF_ENOMEM. */
int dicomweb_search(const struct dicomweb *dw, enum dicomweb_level level, const char *study_uid, const char *series_uid,
                    const struct dicomweb_param *params, int n_params, char **json, size_t *len, struct sf_err *err);

/* WADO-RS of one series: GET {url}/studies/{study}/series/{series}, Accept multipart/related;
 * type="application/dicom"; transfer-syntax=* (the instances as the PACS holds them). */
struct dicomweb_retrieve {
    const char *dir;             /* where the instances go, one file each, "000001.dcm", ... in the
                                  * answer's order, mode 0600, never over an existing file */
    uint64_t max_instance_bytes; /* an instance over this is refused: SF_ELIMIT (the daemon's max_body) */
    int n_expected;              /* instances expected (QIDO's NumberOfSeriesRelatedInstances), for
                                  * progress's fraction; 0: unknown (the fraction stays 0) */
    /* Called once an instance's file is whole and closed (not fsynced), with its 1-based index in
     * the answer and its path: the caller may move it (into the store) or leave it. Non-zero (an
     * SF_E* code, err filled) stops the retrieve with that code. NULL: the files stay in dir. */
    int (*instance)(void *ctx, int index, const char *path, uint64_t n_bytes, struct sf_err *err);
    void *ctx;
    const struct sf_progress *progress; /* polled about once a second and after each instance,
                                         * with instances done / n_expected: a stop answers SF_ECANCEL */
};
/* Streams the series into rq->dir: never more than one network read in memory, each instance
 * capped. The request is tried again (DICOMWEB_ATTEMPTS) only while no instance has begun; after
 * that a broken answer fails. On failure the instance being written is removed; those handed to
 * rq->instance before are the caller's. *n_instances: instances handed over (also on failure).
 * 0; SF_EINVAL (a UID); SF_ENOTFOUND (404, or an answer without instances); SF_ELIMIT (an
 * instance over the cap, more than DICOMWEB_MAX_INSTANCES); SF_EFORMAT (not multipart/related of
 * application/dicom, a broken multipart body); SF_EIO (as dicomweb_search; a file that cannot be
 * written); SF_ECANCEL; rq->instance's code. */
int dicomweb_retrieve_series(const struct dicomweb *dw, const char *study_uid, const char *series_uid,
                             const struct dicomweb_retrieve *rq, int *n_instances, struct sf_err *err);

/* STOW-RS's answer for one instance, in the order of the PACS's answer (which lists instances by
 * UID, not by file: match them by SOP Instance UID). */
struct dicomweb_stored {
    char sop_class_uid[65];
    char sop_instance_uid[65];
    bool stored;    /* listed in ReferencedSOPSequence (0008,1199); false: in FailedSOPSequence (0008,1198) */
    int reason;     /* FailureReason (0008,1197) of a failed one, WarningReason (0008,1196) of a stored
                     * one (0xB000 coerced, ...); 0: none given */
};
/* POST {url}/studies[/{study_uid}] of n_paths DICOM files as one multipart/related body, streamed
 * from the files (each read as it is sent). Answers 0 whenever the PACS gave its per-instance
 * answer (HTTP 200, 202 some warnings, 409 some failed): *results (caller frees with free()) and
 * *n_results say which were stored; an instance the PACS does not list was not. SF_EINVAL (no
 * file, a UID, an empty file); SF_ELIMIT (a file over max_instance_bytes, checked before anything
 * is sent); SF_EIO (a file unreadable or changed while sent; as dicomweb_search); SF_EFORMAT (an
 * answer without the sequences); SF_ENOMEM. */
int dicomweb_store(const struct dicomweb *dw, const char *study_uid, const char *const *paths, int n_paths,
                   uint64_t max_instance_bytes, struct dicomweb_stored **results, int *n_results, struct sf_err *err);

#endif
