#ifndef SURFD_JSON_IN_H
#define SURFD_JSON_IN_H
/* Reading a JSON request body with a bound on the memory its tree takes. */
#include <jansson.h>
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

#endif
