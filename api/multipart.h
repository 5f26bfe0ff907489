/* multipart.h - multipart bodies (RFC 2046): one reader for both of surfd's uses. A series posted
 * as multipart/form-data (RFC 7578: curl -F slice=@IM0001.dcm ...) is split in place
 * (multipart_split); a DICOMweb answer, multipart/related of whole instances (WADO-RS, PS3.18
 * 8.7), is read as it streams in, chunk by chunk, never held whole (struct multipart_reader). Pure
 * parsing: no I/O, no allocation beyond the reader itself. */
#ifndef SURFD_MULTIPART_H
#define SURFD_MULTIPART_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "../core/base/err.h"

#define MULTIPART_MAX_PARTS 10000   /* parts multipart_split gives (the reader counts none) */
#define MULTIPART_MAX_BOUNDARY 200  /* RFC 2046 says 70; longer ones are met and cost nothing */
#define MULTIPART_MAX_HEAD 16384    /* one part's header block: a few lines in practice */

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

/* A parameter of a Content-Type value (RFC 9110 8.3.1: name case-insensitive, value a token or a
 * quoted string, unquoted into out, NUL-terminated). True when present and it fits in cap. */
bool multipart_param(const char *content_type, const char *name, char *out, size_t cap);
/* Whether content_type's media type is type/subtype (case-insensitive, parameters ignored). */
bool multipart_is_type(const char *content_type, const char *type);

/* The streaming reader. Events, in order, for each part: part_begin, part_data (zero or more
 * times, the part's bytes in order, in pieces of any size), part_end. An event answering non-zero
 * stops the reader: that code is what feed answers (the event fills err). Offsets count from the
 * first byte fed. */
struct multipart_events {
    /* head: the part's header lines (CRLF between them, without the empty line ending them;
     * NUL-terminated; borrowed until the call returns), head_at: where they begin, data_at: where
     * the part's data begins */
    int (*part_begin)(void *ctx, const char *head, size_t head_len, uint64_t head_at, uint64_t data_at,
                      struct sf_err *err);
    int (*part_data)(void *ctx, const char *data, size_t len, struct sf_err *err); /* data borrowed */
    int (*part_end)(void *ctx, struct sf_err *err);
    void *ctx;
};
struct multipart_reader;

/* A reader of a body framed by boundary (blen bytes: 1 to MULTIPART_MAX_BOUNDARY printable ASCII
 * characters, as Content-Type's boundary parameter gives it). ev is copied. Caller frees with
 * multipart_reader_free(). 0, SF_EINVAL (the boundary), SF_ENOMEM. */
int multipart_reader_new(const char *boundary, size_t blen, const struct multipart_events *ev,
                         struct multipart_reader **out, struct sf_err *err);
/* The next len bytes of the body. 0; SF_EFORMAT or SF_ELIMIT (a header block over
 * MULTIPART_MAX_HEAD) with pointer "/parts/K"; or an event's code. After a failure every feed
 * answers the same code. Bytes after the closing delimiter (the epilogue) are ignored. */
int multipart_reader_feed(struct multipart_reader *r, const char *data, size_t len, struct sf_err *err);
/* The body's end: 0 when the closing delimiter was read, else SF_EFORMAT (cut short). */
int multipart_reader_finish(struct multipart_reader *r, struct sf_err *err);
/* Parts begun so far. */
int multipart_reader_parts(const struct multipart_reader *r);
void multipart_reader_free(struct multipart_reader *r);

#endif
