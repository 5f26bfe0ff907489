/* dicom_node.h - surfd on the hospital network (issue 44): the DICOM node `surfd serve
 * --dicom-listen PORT --ae-title AET --dicom-peers FILE` runs (dimse.h's SCP), each instance it
 * receives parsed on the node's own workers (never on the association's thread), its identifying
 * elements blanked unless keep-phi, and kept by series in the store (store.h) before the sender
 * hears success; and what GET /series says of a stored series. */
#ifndef SURFD_DICOM_NODE_H
#define SURFD_DICOM_NODE_H

#include "dimse.h"
#include "service.h"

/* The peers file: a peer a line, "AE_TITLE HOST PORT" (HOST a name or an address, resolved here
 * once), # comments and blank lines skipped. 0 (*peers malloc'ed, *n), or SF_EINVAL / SF_EIO
 * with err's message naming the line. */
int dicom_peers_read(const char *path, struct dimse_peer **peers, int *n, struct sf_err *err);

/* An instance (data, len bytes: a DICOM file, blanked here in place unless keep-phi) kept in the
 * store by its series, source saying where it came from; sop (NULL: any) the SOP Instance UID it
 * must have. 0 (also when that SOP Instance UID is stored already), SF_EINVAL / SF_EFORMAT /
 * SF_ELIMIT (not an instance surfd reads), SF_EIO, SF_ENOMEM; err says which. The node's C-STORE
 * and a pull's WADO-RS both keep instances so. */
int dicom_instance_keep(struct service *svc, char *data, size_t len, const char *source, const char *sop,
                        struct sf_err *err);
/* The file at path's bytes (NULL when it is over max bytes or unreadable; malloc'ed, *len). */
char *dicom_file_read(const char *path, size_t max, size_t *len);

/* Removes dir's files and dir (one level: a pull's or the spool). */
void dicom_dir_empty(const char *dir);
/* What a process stopped mid-work (kill -9) left in the data dir: instances arriving (spool/),
 * pulled (pull-JOB/) or being sent (send-JOB.dcm), not yet blanked or kept; at start, before any
 * job runs (a pull or send run again writes them anew). */
void dicom_leftovers_remove(const char *data_dir);

struct dicom_node;
/* Starts the node when cfg.dicom_listen is set (else 0 and *out NULL). 0, or an error said in err. */
int dicom_node_start(struct service *svc, struct dicom_node **out, struct sf_err *err);
void dicom_node_stop(struct dicom_node *n);

/* ?series=UID on POST /isosurface, /matrix-model (one: false) and /model (one: true): the
 * request body a stored series makes, as if it had been posted: its instances as a multipart
 * series, or its one instance (an RT Structure Set). 0 (*body malloc'ed), or SF_EINVAL at
 * "?series" (no such series, several structure sets), SF_ELIMIT (over max_bytes), SF_EIO,
 * SF_EDAMAGED, SF_ENOMEM. */
int series_request(struct service *svc, const char *uid, bool one, size_t max_bytes, char **body, size_t *len,
                   struct sf_err *err);

/* GET /series/{uid} and GET /series: a series' resource (JSON, malloc'ed; NULL without memory).
 * detail: its geometry from its instances' (dims, spacing, orientation) as well. idle_s: seconds
 * without an instance before it counts as complete. */
char *series_resource(struct service *svc, const struct series_rec *r, bool detail);

#endif
