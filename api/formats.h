/* formats.h - every input format surfd reads, in one table (formats.c): its name and the other
 * names ?format= takes, its files' extensions, the media types that name it, how a body that names
 * none is known for it (magic bytes, never a substring found anywhere in the body), and the routes
 * that take it. The routes' media lists (and their 415 answers), ?format=, the offline CLI's and
 * surfctl's choice by extension, GET /formats (the page and the Python client) and openapi.yaml's
 * media (tests/api/formats.sh) all read it. A format's reader stays with its route: the scene
 * parsers (scene_io.h), the contour and RT Structure Set readers (model_json.h), the volumes
 * (volume_io.h); adding a format is one entry here and its reader's file. */
#ifndef SURFD_FORMATS_H
#define SURFD_FORMATS_H

#include <stdbool.h>
#include <stddef.h>

#include "../core/base/err.h"

/* The routes that read a body (a kind's route). */
enum input_route {
    IN_RENDER = 1,     /* POST /render: a scene */
    IN_VOLUME = 2,     /* POST /volume: contours, an RT Structure Set or a scene that closes a solid */
    IN_MODEL = 4,      /* POST /model: contours, an RT Structure Set or a matrix model */
    IN_ISOSURFACE = 8, /* POST /isosurface: a volume or an FRep object */
    IN_MATRIX = 16,    /* POST /matrix-model: the same */
};
#define IN_SCENES (IN_RENDER | IN_VOLUME)
#define IN_VOLUMES (IN_ISOSURFACE | IN_MATRIX)

#define FORMAT_MAX_NAMES 4

struct input_format {
    const char *name;                        /* as ?format= and a job's record say it */
    const char *aliases[FORMAT_MAX_NAMES];   /* other names ?format= takes (NULL-ended) */
    const char *extensions[FORMAT_MAX_NAMES]; /* its files' (".nii.gz" before ".gz"), lower case */
    const char *media[FORMAT_MAX_NAMES];     /* the types that name it, the first the one to send */
    unsigned routes;                         /* enum input_route's */
    bool (*sniff)(const char *buf, size_t len); /* its magic; NULL: never sniffed (raw samples) */
    const char *what;                        /* for people: "NRRD (.nrrd; .nhdr with its data file)" */
};

extern const struct input_format INPUT_FORMATS[];
extern const size_t N_INPUT_FORMATS;

/* The format a Content-Type names on route (its parameters ignored, case-insensitive): the format's
 * name; "" for no type, or one that leaves the body to be sniffed (text/plain, application/gzip,
 * multipart/form-data, curl -d's form type); NULL when route does not read it (415). */
const char *input_format_of_media(const char *content_type, unsigned route);
/* The format ?format=NAME names on route (by its name or an alias, case-insensitive), or NULL. */
const struct input_format *input_format_named(const char *name, unsigned route);
/* The format a file's name says by its extension on route, or NULL. */
const struct input_format *input_format_of_path(const char *path, unsigned route);
/* The first format of route whose magic the body's first bytes carry, or NULL. */
const struct input_format *input_format_sniff(const char *buf, size_t len, unsigned route);
/* What route reads, for people ("NRRD (application/x-nrrd), ..."), into out; and its format names
 * ("json, bpt, nurbs or iges"). */
void input_formats_said(unsigned route, char *out, size_t cap);
void input_format_names(unsigned route, char *out, size_t cap);

/* GET /formats: the table as JSON ({"formats": [{name, aliases, extensions, media, routes: ["/render",
 * ...], sniffed, description}], "sniffed_media": {type: [routes]}}), NULL without memory. */
char *input_formats_json(void);

/* SF_EFORMAT naming what a body is when its magic is a format no route reads (a PNG or JPEG image,
 * a ZIP, a PDF, an STL or STEP file, gzip of something else...), saying what route reads; else 0.
 * For the readers that would otherwise take such a body for their fallback (raw samples, VRML). */
int input_refuse_foreign(const char *buf, size_t len, unsigned route, const char *path, struct sf_err *err);

/* The magic of some formats, for the readers that check a body against its declared format. */
bool format_sniff_nrrd(const char *buf, size_t len);
bool format_sniff_mha(const char *buf, size_t len);
bool format_sniff_dicom(const char *buf, size_t len);
bool format_sniff_json_object(const char *buf, size_t len);

#endif
