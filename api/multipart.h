/* multipart.h - the parts of a multipart/form-data body (RFC 7578), found in place: how a DICOM
 * series is posted, one part per slice (curl -F slice=@IM0001.dcm -F slice=@IM0002.dcm ...). */
#ifndef SURFD_MULTIPART_H
#define SURFD_MULTIPART_H

#include <stdbool.h>
#include <stddef.h>

#include "../core/base/err.h"

#define MULTIPART_MAX_PARTS 10000

struct part {
    const char *data;        /* into the body */
    size_t len;
    const char *filename;    /* the part's filename="..." value, in the body (NULL: none): a slice's file */
    size_t filename_len;     /* name often names the patient, so it is blanked with the series' identity */
};

/* Whether body looks like multipart/form-data: its first line is "--" and a boundary. */
bool multipart_sniff(const char *body, size_t len);
/* The parts (caller frees *parts), the boundary taken from the body's first line. 0, or
 * SF_EFORMAT (pointer "/parts/K": the part that is cut short), SF_ELIMIT. */
int multipart_split(const char *body, size_t len, struct part **parts, int *n, struct sf_err *err);

#endif
