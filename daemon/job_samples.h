/* job_samples.h - what the page's workstation reads besides models (issue 46; job_samples.c): a
 * stored volume's or series' samples as NRRD (GET /models/{id}/volume, /series/{uid}/volume: a
 * transient kind, the body its id, the format "model" or "series"), and the PACS configured
 * (GET /pacs). */
#ifndef SURFD_JOB_SAMPLES_H
#define SURFD_JOB_SAMPLES_H

#include "kinds.h"

extern const struct job_kind samples_kind;
/* {"pacs": [{"name", "protocol": "dicomweb"|"dimse"}]} (malloc'ed; NULL without memory). */
char *pacs_list_json(const struct service *svc);

#endif
