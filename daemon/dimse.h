/* dimse.h - surfd as a DICOM node on the network (issue 44): a storage SCP that answers C-ECHO
 * and C-STORE from the peers allowed (dimse_dcmtk.cpp, DCMTK's dcmnet: its pool of association
 * threads). Each instance is written to a spool file as it arrives (DCMTK writes the bytes as
 * received, never parsing them on the network thread) and handed to the caller's store function,
 * whose answer is the C-STORE response's status: the sender hears success only after the instance
 * is stored. */
#ifndef SURFD_DIMSE_H
#define SURFD_DIMSE_H

#include <stdbool.h>
#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

#include "../core/base/err.h"

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
int dimse_send(const struct dimse_peer *peer, const char *our_ae, const char *const *paths, int n,
               unsigned timeout_s, unsigned *statuses, struct sf_err *err);

#ifdef __cplusplus
}
#endif

#endif
