/* contour_json.h - the contour JSON of API.md §Contours ({"slices": [{"z", "points"}]} or
 * {"z", "contours": [{"points"}]}, with "method", "caps", "parameterisation", "name") into a contour set, with a JSON
 * pointer in every error. The caller frees the set with contour_set_free(). */
#ifndef SURFD_CONTOUR_JSON_H
#define SURFD_CONTOUR_JSON_H

#include <stddef.h>

#include "../core/contour/contour.h"

struct contour_request {
    char name[128];
    char method[24];   /* parabolic (default) */
    char caps[16];     /* flat (default), slab or dome */
    char param[16];    /* arc-length (default) or polar */
};

int contour_parse_json(const char *buf, size_t len, struct contour_set *cs, struct contour_request *req,
                       struct sf_err *err);
/* contour_clean, its fault named by its JSON pointer ("/slices/2/contours/1/points/7",
 * "/slices/2/z", "/slices"): how every reader of contours cleans them. */
int contour_json_clean(struct contour_set *cs, struct sf_err *err);

/* The cleaned set and its options back as contour JSON (every slice in the "contours" form, full
 * double precision, so that parsing it again gives the same model): how a stored model keeps its
 * source. NULL when out of memory; the caller frees. */
char *contour_json_write(const struct contour_set *cs, const struct contour_request *req);

#endif
