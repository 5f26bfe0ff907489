#ifndef SURFD_JSON_IN_H
#define SURFD_JSON_IN_H
/* Reading a JSON request body with a bound on the memory its tree takes. */
#include <jansson.h>
#include <stdbool.h>
#include <stddef.h>

#include "../core/base/err.h"

/* jansson's tree and what is built from it take about 100 bytes of memory a value (measured: a
 * 54 MB array of small numbers took 1.4 GB, 3.9 M values 390 MB), so a body within max-body could
 * still exhaust memory: bodies of more values than this are refused before parsing (about 250 MB
 * at most). Real inputs are well below it: a 30-slice contour set of 20 000 points a slice holds
 * 1.8 M values (points are arrays), a 20 000-patch bicubic scene 1.3 M, the largest shared
 * contour file 0.1 M. */
#define JSON_MAX_VALUES 2500000

/* Parses buf into *root (duplicate keys refused): 0, or SF_ELIMIT over JSON_MAX_VALUES, or
 * SF_EFORMAT (pointer "line L, column C") when it is not JSON. */
int json_read(const char *buf, size_t len, json_t **root, struct sf_err *err);
/* Whether the top-level object has member key, by a scan of the text's structure (no tree; a key
 * spelt with escapes, or a text the scan cannot walk, is not found: the parser then says why). */
bool json_has_member(const char *buf, size_t len, const char *key);

/* A body whose bulk is one array of the top-level object (a scene's "objects": a contour model's
 * patches run to 5.5 M values) is read with that array held back: *root is the document with the
 * array left empty, and its elements are parsed one at a time by json_read_element, each tree
 * freed before the next is read. JSON_MAX_VALUES then bounds the rest and each element, and
 * JSON_MAX_SPLIT_VALUES the whole: what is built from the elements takes 10 to 30 bytes a value,
 * not jansson's 100 (a bicubic patch: 70 values, 560 bytes built). The array is the first of keys
 * (NULL-terminated) that the top-level object holds as an array; where none is found plainly (a
 * key spelt with escapes, a document a quick scan of its brackets cannot walk), this is json_read
 * and sp->held is false. Past max_elements the scan stops: sp->n is then max_elements + 1, for the
 * caller to refuse. */
#define JSON_MAX_SPLIT_VALUES 8000000
struct json_split {
    const char *buf;
    const char *key;       /* the array held back (NULL: none) */
    bool held;
    size_t n;              /* its elements */
    size_t (*range)[2];    /* element k: buf[range[k][0]] .. buf[range[k][1] - 1] */
};
int json_read_split(const char *buf, size_t len, const char *const *keys, size_t max_elements, json_t **root,
                    struct json_split *sp, struct sf_err *err);
/* Element k as a tree (the caller decrefs it), errors as json_read's (the position in the body). */
int json_read_element(const struct json_split *sp, size_t k, json_t **out, struct sf_err *err);
void json_split_free(struct json_split *sp);

#endif
