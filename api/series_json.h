/* series_json.h - DICOM series kept in the store as resources (GET /series, GET /series/{uid}):
 * what an instance's row keeps of its geometry (instance_meta), and a series' resource, its
 * geometry summed from its instances' (dims, spacing, orientation, frame of reference). */
#ifndef SURFD_SERIES_JSON_H
#define SURFD_SERIES_JSON_H

#include <stdbool.h>

#include "dicom_instance.h"

/* An instance's meta as the store keeps it (a JSON object; malloc'ed, NULL without memory). */
char *instance_meta(const struct dicom_instance *in);

struct series_view {
    const char *uid, *study_uid, *modality, *source;
    long instances;
    long long bytes;
    double first, last;      /* when its first and last instance came (Unix seconds) */
    bool complete;           /* no instance for series-idle seconds */
    const char *job;         /* the job made of it when complete (auto-model), or "" */
    /* with detail: its instances' metas (series_json adds their geometry) */
    const char *const *metas;
    int n_metas;
};

/* The series' resource (JSON; malloc'ed, NULL without memory). */
char *series_json(const struct series_view *v);

#endif
