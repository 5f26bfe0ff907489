/* dimse.h - surfd as a DICOM node on the network (issue 44): a storage SCP that answers C-ECHO
 * and C-STORE from the peers allowed (dimse_dcmtk.cpp, DCMTK's dcmnet: its pool of association
 * threads). Each instance is written to a spool file as it arrives (DCMTK writes the bytes as
 * received, never parsing them on the network thread) and handed to the caller's store function,
 * whose answer is the C-STORE response's status: the sender hears success only after the instance
 * is stored. And surfd as an SCU of a PACS: C-STORE to it, C-FIND of its studies and series, C-GET
 * of a series into files. The SCU calls block for the network (a job's worker, or the checks
 * pool for a C-FIND), each bounded by the timeouts below; none of them logs, and no message
 * they write holds a query's value (a C-FIND names patients). */
#ifndef SURFD_DIMSE_H
#define SURFD_DIMSE_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#include "../core/base/err.h"

/* DCMTK's process-wide settings, once, before any thread starts: its own log silenced (it is not
 * the daemon's, and it would print a C-FIND's keys); Nagle's algorithm off on its connections
 * (DCMTK reads TCP_NODELAY from the environment at each connection, and leaves Nagle on by default:
 * each C-STORE response of a C-GET then waits for the peer's delayed ACK, some 90 ms an instance),
 * unless the environment says otherwise. */
void dimse_global_init(void);

/* A peer allowed to associate (and to be sent to): its AE title, its host as an IP address
 * (dicom_node.c resolves names when it reads the peers), its port (for C-STORE to it). */
struct dimse_peer {
    char ae[17];
    char ip[64];
    int port;
};

/* C-STORE response statuses (PS3.4 B.2.3) the store function answers. */
#define DIMSE_SUCCESS 0x0000u
#define DIMSE_OUT_OF_RESOURCES 0xA700u
#define DIMSE_CANNOT_UNDERSTAND 0xC000u

/* path: the spool file (a Part 10 file; removed after the call); calling_ae: the peer's AE title;
 * sop_uid: the request's Affected SOP Instance UID. */
typedef unsigned (*dimse_store_fn)(const char *path, const char *calling_ae, const char *sop_uid, void *arg);

struct dimse_config {
    const char *ae_title;    /* ours: associations calling another are refused */
    int port;
    const struct dimse_peer *peers; /* the only callers accepted (AE title and IP address both) */
    int n_peers;
    const char *spool;       /* a directory of ours (0700) for instances as they arrive */
    size_t max_bytes;        /* an instance longer is refused (the association aborted as it passes) */
    int max_associations;    /* at once; more are refused as busy */
    dimse_store_fn store;
    void *arg;
};

struct dimse_scp;
/* Listens on cfg->port (every interface: Debian's DCMTK 3.6.7 binds no address) in a thread of its
 * own: 0 (*out), or SF_EIO with err's message (the port is taken). cfg's strings and peers are
 * copied. */
int dimse_scp_start(const struct dimse_config *cfg, struct dimse_scp **out, struct sf_err *err);
/* Stops listening, lets the associations running end (each within DCMTK's timeouts), frees. */
void dimse_scp_stop(struct dimse_scp *s);

/* C-STORE of n Part 10 files to peer (one association, our AE title calling its): statuses[k] the
 * peer's status for file k (DIMSE_SUCCESS, a warning 0xB..., a failure), or DIMSE_NOT_SENT when it
 * was not sent (the association failed, or no presentation context for its SOP class). 0 when the
 * association ran (each file's status then says), SF_EIO when it could not be made (the peer down
 * or refusing: err says which), within the timeouts given (seconds). */
#define DIMSE_NOT_SENT 0xFFFFu
/* The SCU's bounds, each what it trades. */
#define DIMSE_CONNECT_TIMEOUT_S 5 /* a TCP connection: a PACS on the LAN answers in ms; DCMTK keeps
                                   * this one value for the process, so every SCU call uses it */
#define DIMSE_QUERY_TIMEOUT_S 30  /* association and silence between two C-FIND responses */
#define DIMSE_SEARCH_TOTAL_S 30   /* a whole C-FIND: it holds a checks thread (GET /pacs/{name}/studies) */
#define DIMSE_GET_TIMEOUT_S 60    /* silence in a C-GET: a PACS may fetch from its archive first */
#define DIMSE_MAX_MATCHES 10000   /* C-FIND matches kept (then a C-CANCEL): QIDO's limit at most */
#define DIMSE_MAX_ANSWER (16u << 20) /* the C-FIND answer's JSON (dicomweb.h's cap) */
#define DIMSE_MAX_MATCH_BYTES (1u << 20) /* one C-FIND response's data set (some hundred bytes) */
int dimse_send(const struct dimse_peer *peer, const char *our_ae, const char *const *paths, int n,
               unsigned timeout_s, unsigned *statuses, struct sf_err *err);

/* C-FIND in the Study Root model (PS3.4 C.6.2) at one level: studies, or the series of study_uid. */
enum dimse_level { DIMSE_STUDIES, DIMSE_SERIES };
struct dimse_key {
    const char *name;  /* an attribute's keyword ("PatientID") or tag as 8 hex digits ("00100020");
                        * or QIDO's "limit", "offset", "includefield" (a keyword, a tag, or "all":
                        * ignored), "fuzzymatching" (ignored: C-FIND has none, and QIDO lets a
                        * server ignore it) */
    const char *value; /* a C-FIND matching key as written ("19*", "20240101-20241231"); empty:
                        * return the attribute */
};
/* The level's usual return keys are asked for (studies: StudyInstanceUID, StudyDate, StudyTime,
 * StudyDescription, AccessionNumber, PatientID, PatientName, ModalitiesInStudy,
 * NumberOfStudyRelatedSeries and Instances; series: SeriesInstanceUID, Modality, SeriesNumber,
 * SeriesDescription, NumberOfSeriesRelatedInstances), and the keys'. *json: the matches as a DICOM
 * JSON array (PS3.18 F.2), as QIDO-RS answers them ("[]": none), in UTF-8 where the PACS's
 * character set converts; caller frees with free(). 0; SF_EINVAL (a key that is no attribute, a
 * sequence, a bad limit: err's pointer "?NAME"); SF_ELIMIT (over DIMSE_MAX_ANSWER, or a response
 * over DIMSE_MAX_MATCH_BYTES); SF_EIO (unreachable, refused, timed out, a failure status);
 * SF_ENOMEM. */
int dimse_find(const struct dimse_peer *peer, const char *our_ae, enum dimse_level level, const char *study_uid,
               const struct dimse_key *keys, int n_keys, char **json, size_t *len, struct sf_err *err);

/* C-GET (Study Root) of a series, or of a whole study (series_uid NULL), on one association: the
 * PACS sends each instance back on it by C-STORE (the storage SOP classes DCMTK's SCUs propose,
 * surfd in the SCP role), each written to a file in dir as received and handed to instance; the
 * PACS hears success only once instance answered 0. */
struct dimse_retrieve {
    const char *dir;             /* ours (0700): each instance a file while instance runs */
    uint64_t max_instance_bytes; /* one longer aborts the association as it passes: SF_ELIMIT */
    /* index: 1-based, in arrival order; path: removed after the call. Non-zero (an SF_E* code,
     * err filled) stops the retrieve with that code (the PACS told 0xC000, the association
     * aborted). */
    int (*instance)(void *ctx, int index, const char *path, uint64_t n_bytes, struct sf_err *err);
    void *ctx;
    const struct sf_progress *progress; /* polled after each instance and each pending response,
                                         * with completed / (completed + remaining): a stop aborts
                                         * the association, SF_ECANCEL */
};
/* 0 when the PACS sent every instance it matched (*n_instances: those handed over); SF_ENOTFOUND
 * (it matched none); SF_EIO (unreachable, refused, no C-GET, timed out, broken off, or some
 * instances not sent: err says how many); SF_ELIMIT; SF_ECANCEL; instance's code. Instances
 * handed over before a failure are the caller's. */
int dimse_get(const struct dimse_peer *peer, const char *our_ae, const char *study_uid, const char *series_uid,
              const struct dimse_retrieve *rq, int *n_instances, struct sf_err *err);

#ifdef __cplusplus
}
#endif

#endif
