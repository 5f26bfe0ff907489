/* volume_io.h - the volumes POST /isosurface reads (API.md §Volumes): raw samples with their
 * layout in the query (?dims=X,Y,Z&type=uint8|int16|uint16|float32&spacing=sx,sy,sz
 * &origin=ox,oy,oz), NRRD with an attached header (raw or gzip encoding), MetaImage .mha
 * (ElementDataFile = LOCAL), a DICOM CT or MR series as multipart/form-data, or one multi-frame
 * DICOM image (Enhanced CT/MR, RT Dose, Segmentation: ?segment=N) (dicom_series.h), and
 * an FRep object's JSON (frep_json.h), whose grid is sampled from its function (volume_sample).
 * Samples are used where they lie in the body when they can be (raw encoding in the host's byte
 * order), decoded otherwise; core/iso sees only the grid.
 *
 * Label maps (integer raw, NRRD, MetaImage or NIfTI samples, 0 the background): ?label=N reads the
 * map as N's mask (uint8 0/1, iso 0.5: its surface is the mask's isosurface); ?labels=all as a
 * grid of label indices (1 .. n_labels, by increasing value; core/iso/labels.h makes one surface
 * each), the labels' names taken from the file where it gives them (NRRD's Segment<k>_Name and
 * Segment<k>_LabelValue as 3D Slicer writes them, a NIfTI label table extension or intent_name;
 * else "label N"). */
#ifndef SURFD_VOLUME_IO_H
#define SURFD_VOLUME_IO_H

#include <stddef.h>

#include "../core/base/err.h"
#include "../core/iso/adapt.h"
#include "../core/iso/mc.h"
#include "frep_json.h"

/* Samples a volume may have (query options and headers are checked against it before anything
 * is allocated): 2^31, a 1290^3 grid, 4 GB of int16. */
#define VOLUME_MAX_SAMPLES (1ull << 31)
/* Labels of one map ?labels=all reads at most (a node may take fewer: max-labels), and the
 * bytes of a label's name kept. */
#define VOLUME_MAX_LABELS 4096
#define VOLUME_LABEL_NAME 64

/* A label of a map: its value and name. */
struct volume_label {
    long long value;
    char name[VOLUME_LABEL_NAME];
};

struct volume {
    struct iso_grid g;
    void *owned;             /* decoded samples, when the body's could not be used in place */
    double iso;              /* ?iso */
    bool closed;             /* ?closed (default true) */
    int levels;              /* ?levels (1..ISO_MAX_LEVELS, default 1: every cell at full resolution) */
    double max_error;        /* ?max_error (mm; default half the smallest spacing) */
    bool sharp;              /* ?features=sharp (default none) */
    bool pieces;             /* ?merge=pieces: a vertex per piece of surface in a merged cell (default cells) */
    char name[128];          /* ?name */
    bool check_only;         /* volume_check: the samples are not read */
    double axes[3][3];       /* the grid's x, y, z directions (a DICOM series may be oblique) */
    bool oblique;            /* axes are not the identity: the mesh is turned by them about the origin */
    struct frep_request *frep; /* an FRep object: its float32 grid is filled by volume_sample() */
    const char *source;      /* "isosurface" (sampled) or "frep", as the model resource says */
    /* label maps */
    bool integer;            /* the samples as stored are whole numbers (integer types, NIfTI's unscaled) */
    bool has_label;          /* ?label=N: the grid is N's mask */
    long long label;         /* N */
    bool all_labels;         /* ?labels=all: the grid holds label indices */
    int n_labels;            /* the labels found (indices 1 .. n_labels; ?label: 1, N) */
    enum iso_type map_type;  /* the map's own samples' type (g.type is then the mask's or indices') */
    struct volume_label *label_of; /* their values and names, index k at [k - 1] */
    struct volume_label *named; /* the labels the file names (n_named; values may repeat: the last wins) */
    int n_named, cap_named;
    char map_name[17];       /* a NIfTI's intent_name, naming its unnamed labels "NAME N" */
    char series_uid[65], study_uid[65], frame_uid[65]; /* a DICOM series': its UIDs (dicom_series.h), else "" */
};

/* The body's format from its Content-Type on the volume routes (formats.h's table): "raw"
 * (application/octet-stream: a NRRD, MetaImage, NIfTI or DICOM file posted so, without ?dims, is
 * read as what it is), "nrrd", "mha", "nifti", "dicom", "frep" (application/json); "" for a body to
 * sniff (no type, application/gzip, multipart/form-data: a DICOM series or a detached header with
 * its data file); NULL for others (415). */
const char *volume_format_from_type(const char *content_type);
/* The format volume_read reads the body as: "nrrd" or "mha" for a multipart body of a detached
 * header and its data file; format itself, but for "" (sniffed), "dicom" and "raw": "nifti" for a
 * NIfTI header (gzip or not), else "raw" when options give dims; then by the formats' magic
 * (formats.h: an FRep's JSON object for "" alone, DICOM, NRRD, MetaImage), "dicom" for another
 * multipart body (a series), else "raw". */
const char *volume_format_of(const char *body, size_t len, const char *format, const char *options);

/* A detached header (NRRD's "data file: F", MetaImage's "ElementDataFile = F", not LOCAL, a list
 * or a pattern): F into name (cap bytes) and the number of the header line that names it; 0 when
 * buf names none. The daemon reads attached headers only (an upload is one body); the offline
 * CLI attaches F's samples itself. */
int volume_data_file(const char *buf, size_t len, char *name, size_t cap);
/* The detached header hdr made whole, as one body volume_read takes: its data file line (number
 * line, from volume_data_file) dropped (MetaImage: ElementDataFile = LOCAL in its place, last), the
 * data file's bytes after the header (NRRD: after a blank line). Its length into *out_len; NULL
 * without memory. */
char *volume_attach(const char *hdr, size_t len, int line, const char *data, size_t data_len, size_t *out_len);

/* Reads a volume: format "raw", "nrrd", "mha", "nifti", "dicom", "frep" or "" (sniffed); options the query. On success
 * v->g.samples points into body or v->owned (free with volume_free). Errors name the query option
 * ("?dims"), or the header line ("header line 4: ...") of what is wrong: SF_EINVAL (422),
 * SF_EFORMAT (400: not a volume of that format), SF_ELIMIT (too many samples). The grid's origin,
 * far corner and spacings, and ?iso, are in ranges.h's ranges (iso also within what the samples'
 * type holds), else SF_EINVAL naming ?origin, ?spacing, ?iso, the header line, an FRep's /bounds
 * or /cell, or a series' /parts. */
int volume_read(const char *body, size_t len, const char *format, const char *options, struct volume *v,
                struct sf_err *err);
/* The name of v's label index k (1 .. n_labels): ?name, when given, before the label's own. */
void volume_label_name(const struct volume *v, int k, char *out, size_t cap);
void volume_free(struct volume *v);
/* Frees v's samples (and FRep object), keeping what describes it (its grid, options, labels). */
void volume_drop_samples(struct volume *v);
/* 0, or SF_EINVAL at ?iso when the mesh m extracted from v is empty: every sample on one side of
 * iso (an FRep object: nothing inside its bounds), which a user wants said, not stored. */
int volume_mesh_empty(const struct volume *v, const struct trimesh *m, struct sf_err *err);
/* The extraction's options for v (an FRep's own function for its crossings with features=sharp),
 * and whether it takes the adaptive hierarchy (levels over 1, or features). */
struct iso_opts volume_iso_opts(const struct volume *v);
bool volume_adaptive(const struct volume *v);
/* Fills planes [z0, z1) of an FRep volume's grid (any planes, on any threads); nothing for
 * sampled volumes. 0, or SF_ECANCEL when pr asks to stop (polled every 8^3 samples). */
int volume_sample(struct volume *v, int z0, int z1, const struct sf_progress *pr, struct sf_err *err);
/* What volume_read says of the query and the header and the body's length, without reading the
 * samples (no inflating, no NaN scan): cheap enough for the HTTP thread that takes the upload.
 * The job's volume_read says the rest. max_labels (0: VOLUME_MAX_LABELS): with ?labels=all, a
 * header that names more labels than that is SF_ELIMIT at ?labels. */
int volume_check(const char *body, size_t len, const char *format, const char *options, int max_labels,
                 struct sf_err *err);

/* An edit's block (POST /models/{id}/edit): ?region=x0,y0,z0,nx,ny,nz inside grid g, the body
 * of len bytes holding its samples in g's type (x fastest, the host's byte order). 0, or
 * SF_EINVAL at ?region (or at the body, "", for its length). */
int volume_region(const char *options, const struct iso_grid *g, size_t len, int lo[3], int n[3], struct sf_err *err);

#endif
