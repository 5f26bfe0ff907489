/* volume_io.c - raw, NRRD (attached header), MetaImage (.mha), DICOM series and FRep volumes
 * (volume_io.h), and label maps read as a label's mask or as label indices. The two header formats
 * are a handful of "key: value" / "Key = Value" lines: read here by hand (teem and ITK would bring
 * whole toolkits for it), 3D Slicer's segment names among them; gzip and zlib data through zlib;
 * a DICOM series through dicom_series.h's DCMTK shim, an FRep object through frep_json.h. */
#include "volume_io.h"

#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <zlib.h>

#include "dicom_series.h"
#include "formats.h"
#include "multipart.h"
#include "nifti.h"
#include "query.h"
#include "ranges.h"

static const char *pair_format(const char *body, size_t len);

const char *volume_format_of(const char *body, size_t len, const char *format, const char *options)
{
    const char *pair = !*format || !strcmp(format, "dicom") || !strcmp(format, "raw") ? pair_format(body, len) : NULL;
    if (pair) /* a multipart body of a detached header and its data file */
        return pair;
    if (*format && strcmp(format, "raw"))
        return format;
    char dims[8];
    query_option(options, "dims", dims, sizeof dims);
    /* a file posted as octet-stream is what it is (a NIfTI header is no raw samples' chance bytes,
     * so a NIfTI file's ?dims is refused as its header's); dims make anything else raw samples */
    if (nifti_sniff_body(body, len))
        return "nifti";
    if (dims[0])
        return "raw";
    const struct input_format *f = input_format_sniff(body, len, IN_ISOSURFACE); /* by their magic (formats.h) */
    if (f && !(*format && !strcmp(f->name, "frep"))) /* (JSON posted as octet-stream is no FRep) */
        return f->name;
    return multipart_sniff(body, len) ? "dicom" : "raw";
}

const char *volume_format_from_type(const char *ct) { return input_format_of_media(ct, IN_ISOSURFACE); }

static size_t type_size(enum iso_type t) { return t == ISO_U8 ? 1 : t == ISO_F32 ? 4 : 2; }

static int parse_type(const char *s, enum iso_type *t)
{
    static const struct {
        const char *name;
        enum iso_type type;
    } NAMES[] = {{"uint8", ISO_U8},          {"uchar", ISO_U8},          {"unsigned char", ISO_U8},
                 {"uint8_t", ISO_U8},        {"MET_UCHAR", ISO_U8},      {"int16", ISO_I16},
                 {"short", ISO_I16},         {"short int", ISO_I16},     {"signed short", ISO_I16},
                 {"int16_t", ISO_I16},       {"MET_SHORT", ISO_I16},     {"uint16", ISO_U16},
                 {"ushort", ISO_U16},        {"unsigned short", ISO_U16}, {"uint16_t", ISO_U16},
                 {"MET_USHORT", ISO_U16},    {"float32", ISO_F32},       {"float", ISO_F32},
                 {"MET_FLOAT", ISO_F32}};
    for (size_t k = 0; k < sizeof NAMES / sizeof *NAMES; k++)
        if (!strcmp(s, NAMES[k].name)) {
            *t = NAMES[k].type;
            return 0;
        }
    return -1;
}

/* n numbers separated by commas or blanks (parentheses ignored) into out: 0, or -1. */
static int numbers(const char *s, int n, double *out)
{
    for (int k = 0; k < n; k++) {
        while (*s && (isspace((unsigned char)*s) || *s == ',' || *s == '(' || *s == ')'))
            s++;
        char *end;
        out[k] = strtod(s, &end);
        if (end == s || !isfinite(out[k]))
            return -1;
        s = end;
    }
    while (*s && (isspace((unsigned char)*s) || *s == ')'))
        s++;
    return *s ? -1 : 0;
}

/* dims: three integers >= 2 whose product is within the limit. */
static int check_dims(const double d[3], const char *where, int dims[3], struct sf_err *err)
{
    double total = 1;
    for (int a = 0; a < 3; a++) {
        if (d[a] != floor(d[a]) || d[a] < 2 || d[a] > 1e6)
            return sf_fail(err, SF_EINVAL, where, "sizes are three whole numbers from 2 to 1000000");
        dims[a] = (int)d[a];
        total *= d[a];
    }
    if (total > (double)VOLUME_MAX_SAMPLES)
        return sf_fail(err, SF_ELIMIT, where, "%.0f samples is over the limit of %llu", total,
                       (unsigned long long)VOLUME_MAX_SAMPLES);
    return 0;
}

/* What names a grid's origin, spacing and far corner in a request: the pointers (the query option,
 * the header line) and the fields' own names (?origin, "space origin", Offset). */
struct grid_fields {
    const char *origin_at, *origin;
    const char *spacing_at, *spacing;
    const char *corner_at;   /* the far corner: origin + (sizes - 1) x spacing, or the bounds' second */
};

/* A grid's geometry within ranges.h's: its origin lo and far corner hi within RANGE_MAX_COORD of
 * 0, its spacings sp within [RANGE_MIN_SPACING, RANGE_MAX_SPACING] and not finer than float32
 * vertices (the mesh's) hold apart where the grid lies. */
static int check_grid(const double lo[3], const double hi[3], const double sp[3], const struct grid_fields *f,
                      struct sf_err *err)
{
    for (int a = 0; a < 3; a++) {
        char axis = (char)('x' + a);
        if (!(fabs(lo[a]) <= RANGE_MAX_COORD))
            return sf_fail(err, SF_EINVAL, f->origin_at, "%s: %c is %g mm; a volume lies within %g mm of 0", f->origin,
                           axis, lo[a], RANGE_MAX_COORD);
        if (!(sp[a] >= RANGE_MIN_SPACING && sp[a] <= RANGE_MAX_SPACING))
            return sf_fail(err, SF_EINVAL, f->spacing_at, "%s: %g mm along %c; spacings are from %g to %g mm",
                           f->spacing, sp[a], axis, RANGE_MIN_SPACING, RANGE_MAX_SPACING);
        if (!(fabs(hi[a]) <= RANGE_MAX_COORD))
            return sf_fail(err, SF_EINVAL, f->corner_at, "the grid reaches %g mm along %c (%s plus its samples "
                           "times %s); a volume lies within %g mm of 0", hi[a], axis, f->origin, f->spacing,
                           RANGE_MAX_COORD);
        double far = fmax(fabs(lo[a]), fabs(hi[a]));
        if (sp[a] < far * RANGE_MIN_CELL_REL)
            return sf_fail(err, SF_EINVAL, f->spacing_at, "%s: cells of %g mm along %c, %g mm from 0, are finer than "
                           "the mesh's float32 vertices hold apart there (%g mm at least): move %s nearer 0",
                           f->spacing, sp[a], axis, far, far * RANGE_MIN_CELL_REL, f->origin);
    }
    return 0;
}

/* check_grid for a grid of n samples from origin o, sp apart. */
static int check_samples(const int n[3], const double o[3], const double sp[3], const struct grid_fields *f,
                         struct sf_err *err)
{
    double hi[3];
    for (int a = 0; a < 3; a++)
        hi[a] = o[a] + (n[a] - 1) * sp[a];
    return check_grid(o, hi, sp, f, err);
}

/* ---- the samples ---- */

/* Inflates a gzip (or zlib) stream of exactly want bytes into a new buffer. */
static int inflate_all(const char *src, size_t n, size_t want, void **out, struct sf_err *err)
{
    unsigned char *dst = malloc(want ? want : 1);
    if (!dst)
        return sf_fail(err, SF_ENOMEM, "", "out of memory for %zu bytes of samples", want);
    z_stream z = {0};
    if (inflateInit2(&z, 15 + 32) != Z_OK) { /* +32: gzip or zlib header, found by its magic */
        free(dst);
        return sf_fail(err, SF_EBACKEND, "", "zlib would not start");
    }
    const size_t STEP = 1u << 30; /* avail_in and avail_out are 32-bit */
    z.next_in = (unsigned char *)(uintptr_t)src;
    z.next_out = dst;
    int rc = Z_OK;
    while (rc == Z_OK) {
        if (z.avail_in == 0) {
            size_t left = n - (size_t)z.total_in;
            z.avail_in = (unsigned)(left < STEP ? left : STEP);
        }
        if (z.avail_out == 0) {
            size_t left = want - (size_t)z.total_out;
            z.avail_out = (unsigned)(left < STEP ? left : STEP);
        }
        rc = inflate(&z, Z_NO_FLUSH); /* Z_BUF_ERROR: no progress possible (too short, or too long) */
    }
    size_t done = (size_t)z.total_out;
    inflateEnd(&z);
    if (rc != Z_STREAM_END || done != want) {
        free(dst);
        return sf_fail(err, SF_EINVAL, "", "the compressed samples do not inflate to %zu bytes (dims x type)", want);
    }
    *out = dst;
    return 0;
}

/* 0, or SF_EINVAL at where when a float32 sample of v is NaN or infinite. */
static int finite_samples(const struct volume *v, const char *where, struct sf_err *err)
{
    if (v->g.type != ISO_F32)
        return 0;
    const float *f = v->g.samples;
    size_t count = (size_t)v->g.nx * (size_t)v->g.ny * (size_t)v->g.nz;
    for (size_t i = 0; i < count; i++)
        if (!isfinite(f[i])) {
            size_t x = i % (size_t)v->g.nx, y = i / (size_t)v->g.nx % (size_t)v->g.ny,
                   z = i / ((size_t)v->g.nx * (size_t)v->g.ny);
            return sf_fail(err, SF_EINVAL, where, "sample (%zu, %zu, %zu) is not a finite number: NaN and infinite "
                           "samples are refused, not taken as outside", x, y, z);
        }
    return 0;
}

/* Points v at the samples: in place when they are raw, in the host's order and aligned; copied
 * (swapped) or inflated otherwise. Then refuses samples that are not finite. */
static int place_samples(const char *data, size_t n, bool compressed, bool big_endian, const char *where,
                         struct volume *v, struct sf_err *err)
{
    size_t ts = type_size(v->g.type);
    size_t count = (size_t)v->g.nx * (size_t)v->g.ny * (size_t)v->g.nz, want = count * ts;
    int rc;
    if (v->check_only) { /* the layout only: what can be said without reading the samples */
        if (!compressed && n != want)
            return sf_fail(err, SF_EINVAL, where, "%zu bytes of samples, but dims x type make %zu", n, want);
        return 0;
    }
    if (compressed) {
        if ((rc = inflate_all(data, n, want, &v->owned, err)))
            return rc;
    } else {
        if (n != want)
            return sf_fail(err, SF_EINVAL, where, "%zu bytes of samples, but dims x type make %zu", n, want);
        if (big_endian || (uintptr_t)data % ts) {
            if (!(v->owned = malloc(want ? want : 1)))
                return sf_fail(err, SF_ENOMEM, "", "out of memory for %zu bytes of samples", want);
            memcpy(v->owned, data, want);
        }
    }
    unsigned char *b = v->owned;
    if (big_endian && ts > 1) /* little-endian hosts: every machine surfd is built for */
        for (size_t i = 0; i < count; i++)
            for (size_t k = 0; k < ts / 2; k++) {
                unsigned char t = b[i * ts + k];
                b[i * ts + k] = b[i * ts + ts - 1 - k];
                b[i * ts + ts - 1 - k] = t;
            }
    v->g.samples = v->owned ? v->owned : (const void *)data;
    return finite_samples(v, where, err);
}

/* ---- headers ---- */

/* The header's lines up to its end (NRRD: a blank line; MetaImage: the ElementDataFile line):
 * each line to fn(key, value, line number) with the key and value trimmed. *data_at: where the
 * samples start. sep: ':' (NRRD) or '=' (MetaImage). */
typedef int (*header_fn)(void *ctx, const char *key, const char *value, int line, struct sf_err *err);

/* Lines a header may have: 3D Slicer writes some ten key/value pairs a segment. */
#define HEADER_MAX_LINES 4096

static int header_lines(const char *buf, size_t len, char sep, bool mha, bool to_end, header_fn fn, void *ctx,
                        size_t *data_at, struct sf_err *err)
{
    size_t at = 0;
    for (int line = 1; at < len && line <= HEADER_MAX_LINES; line++) {
        const char *nl = memchr(buf + at, '\n', len - at);
        if (!nl)
            return sf_fail(err, SF_EFORMAT, "header", "the header does not end (no sample data after it)");
        size_t n = (size_t)(nl - (buf + at));
        char text[1024];
        if (n >= sizeof text)
            return sf_fail(err, SF_EFORMAT, "header", "header line %d is over %zu characters", line, sizeof text - 1);
        memcpy(text, buf + at, n);
        text[n] = 0;
        if (n && text[n - 1] == '\r')
            text[--n] = 0;
        at += (size_t)(nl - (buf + at)) + 1;
        if (!mha && n == 0) { /* NRRD: a blank line ends the header */
            *data_at = at;
            return 0;
        }
        if (line == 1 && !mha)
            continue; /* the magic, checked by the caller */
        if (text[0] == '#' || n == 0)
            continue;
        char *s = strchr(text, sep);
        if (!s)
            return sf_fail(err, SF_EFORMAT, "header", "header line %d is not \"key%c value\"", line, sep);
        *s = 0;
        char *key = text, *value = s + 1 + (!mha && s[1] == '=') /* NRRD "key:=value" */;
        while (*value && isspace((unsigned char)*value))
            value++;
        for (char *e = key + strlen(key); e > key && isspace((unsigned char)e[-1]);)
            *--e = 0;
        for (char *e = value + strlen(value); e > value && isspace((unsigned char)e[-1]);)
            *--e = 0;
        int rc = fn(ctx, key, value, line, err);
        if (rc > 0) { /* MetaImage: ElementDataFile = LOCAL ends the header */
            *data_at = at;
            return 0;
        }
        if (rc)
            return rc;
    }
    if (to_end && at == len) { /* a detached header: its end ends it */
        *data_at = at;
        return 0;
    }
    return sf_fail(err, SF_EFORMAT, "header", "the header does not end within %d lines", HEADER_MAX_LINES);
}

/* A segment of a 3D Slicer segmentation's header (Segment<k>_Name, Segment<k>_LabelValue). */
struct segment {
    int k;
    long long value;
    bool has_value;
    char name[VOLUME_LABEL_NAME];
};

struct header {
    double dims[3], spacing[3], origin[3];
    bool have_dims, have_type, have_spacing, compressed, big_endian;
    bool detached;      /* its samples come in another part (read_pair): a data file line is taken */
    int data_file_line; /* ... the line that names it */
    enum iso_type type;
    int spacing_line, origin_line; /* the lines that gave them (0: the defaults) */
    struct segment *seg;     /* NRRD: the segments named, in the order first seen */
    int n_seg, cap_seg;
};

static int bad_line(struct sf_err *err, int line, const char *what)
{
    char where[32];
    snprintf(where, sizeof where, "header line %d", line);
    return sf_fail(err, SF_EINVAL, where, "%s", what);
}

/* A name made one line of UTF-8 text, in place: control bytes as blanks, each byte of what is not
 * UTF-8 (a Latin-1 name, a sequence cut at the end) as '?'. */
static void utf8_name(char *name)
{
    for (unsigned char *p = (unsigned char *)name; *p;) {
        int n = *p < 0x80 ? 1 : (*p & 0xe0) == 0xc0 ? 2 : (*p & 0xf0) == 0xe0 ? 3 : (*p & 0xf8) == 0xf0 ? 4 : 0;
        unsigned long c = n == 1 ? *p : n == 2 ? *p & 0x1fu : n == 3 ? *p & 0x0fu : *p & 0x07u;
        int k = 1;
        while (k < n && (p[k] & 0xc0) == 0x80)
            c = c << 6 | (p[k++] & 0x3fu);
        static const unsigned long LEAST[5] = {0, 0, 0x80, 0x800, 0x10000};
        if (n == 0 || k < n || c < LEAST[n] || c > 0x10ffff || (c >= 0xd800 && c <= 0xdfff)) {
            *p++ = '?';
            continue;
        }
        if (n == 1 && (*p < 0x20 || *p == 0x7f))
            *p = ' ';
        p += n;
    }
}

/* A label's name the file gives, kept in v (the last of a value wins); false without memory. */
static bool name_label(struct volume *v, long long value, const char *name, size_t n)
{
    if (v->n_named == v->cap_named) {
        int cap = v->cap_named ? 2 * v->cap_named : 16;
        struct volume_label *p = cap <= 2 * VOLUME_MAX_LABELS ? realloc(v->named, sizeof *p * (size_t)cap) : NULL;
        if (!p)
            return false;
        v->named = p, v->cap_named = cap;
    }
    struct volume_label *l = &v->named[v->n_named++];
    l->value = value;
    n = n < sizeof l->name - 1 ? n : sizeof l->name - 1;
    memcpy(l->name, name, n);
    l->name[n] = 0;
    utf8_name(l->name);
    return true;
}

/* A Segment<k>_Name or Segment<k>_LabelValue line: 0, 1 when key is neither, or SF_EINVAL. */
static int segment_line(struct header *h, const char *key, const char *value, int line, struct sf_err *err)
{
    const char *p = key + 7;
    if (strncmp(key, "Segment", 7) || !isdigit((unsigned char)*p))
        return 1;
    long k = 0;
    while (isdigit((unsigned char)*p) && k <= 2 * VOLUME_MAX_LABELS)
        k = 10 * k + (*p++ - '0');
    bool is_name = !strcmp(p, "_Name"), is_value = !strcmp(p, "_LabelValue");
    if ((!is_name && !is_value) || k > 2 * VOLUME_MAX_LABELS) /* (its other keys; segments past any map's labels) */
        return 1;
    int at = h->n_seg - 1;
    while (at >= 0 && h->seg[at].k != (int)k)
        at--;
    if (at < 0) {
        if (h->n_seg == h->cap_seg) {
            int cap = h->cap_seg ? 2 * h->cap_seg : 16;
            struct segment *s = realloc(h->seg, sizeof *s * (size_t)cap);
            if (!s)
                return sf_fail(err, SF_ENOMEM, "", "out of memory for the header's segments");
            h->seg = s, h->cap_seg = cap;
        }
        at = h->n_seg++;
        memset(&h->seg[at], 0, sizeof h->seg[at]);
        h->seg[at].k = (int)k;
    }
    struct segment *s = &h->seg[at];
    if (is_name) {
        snprintf(s->name, sizeof s->name, "%s", value);
        return 0;
    }
    char *end;
    s->value = strtoll(value, &end, 10);
    if (end == value || *end)
        return bad_line(err, line, "a segment's LabelValue is a whole number");
    s->has_value = true;
    return 0;
}


static int nrrd_line(void *ctx, const char *key, const char *value, int line, struct sf_err *err)
{
    struct header *h = ctx;
    int seg = segment_line(h, key, value, line, err);
    if (seg <= 0)
        return seg;
    if (!strcmp(key, "type")) {
        if (parse_type(value, &h->type))
            return bad_line(err, line, "type is uint8, int16, uint16 or float");
        h->have_type = true;
    } else if (!strcmp(key, "dimension")) {
        if (strcmp(value, "3"))
            return bad_line(err, line, "a volume has dimension 3");
    } else if (!strcmp(key, "sizes")) {
        if (numbers(value, 3, h->dims))
            return bad_line(err, line, "sizes are three whole numbers");
        h->have_dims = true;
    } else if (!strcmp(key, "spacings")) {
        if (numbers(value, 3, h->spacing))
            return bad_line(err, line, "spacings are three numbers");
        h->have_spacing = true;
        h->spacing_line = line;
    } else if (!strcmp(key, "space directions")) {
        double d[9];
        if (numbers(value, 9, d))
            return bad_line(err, line, "space directions are three vectors (a,b,c)");
        for (int a = 0; a < 3; a++)
            for (int b = 0; b < 3; b++)
                if (a != b && d[3 * a + b] != 0)
                    return bad_line(err, line, "an oblique volume (space directions off the axes) is not read; resample it");
        for (int a = 0; a < 3; a++)
            h->spacing[a] = fabs(d[4 * a]);
        h->have_spacing = true;
        h->spacing_line = line;
    } else if (!strcmp(key, "space origin")) {
        if (numbers(value, 3, h->origin))
            return bad_line(err, line, "the space origin is (x,y,z)");
        h->origin_line = line;
    } else if (!strcmp(key, "endian")) {
        if (strcmp(value, "little") && strcmp(value, "big"))
            return bad_line(err, line, "endian is little or big");
        h->big_endian = !strcmp(value, "big");
    } else if (!strcmp(key, "encoding")) {
        if (!strcmp(value, "gzip") || !strcmp(value, "gz"))
            h->compressed = true;
        else if (strcmp(value, "raw"))
            return bad_line(err, line, "encoding is raw or gzip");
    } else if (!strcmp(key, "data file") || !strcmp(key, "datafile")) {
        if (!h->detached)
            return bad_line(err, line, "a detached header (data file) names a file the body does not hold: post the "
                                       "NRRD with its data attached, or the header and its data file as two parts of "
                                       "multipart/form-data");
        h->data_file_line = line;
    } else if (!strcmp(key, "line skip") || !strcmp(key, "byte skip")) {
        if (strcmp(value, "0"))
            return bad_line(err, line, "skips are not read");
    }
    return 0; /* other fields (space, kinds, content...) do not change the samples */
}

static int mha_line(void *ctx, const char *key, const char *value, int line, struct sf_err *err)
{
    struct header *h = ctx;
    if (!strcmp(key, "ObjectType")) {
        if (strcmp(value, "Image"))
            return bad_line(err, line, "ObjectType is Image");
    } else if (!strcmp(key, "NDims")) {
        if (strcmp(value, "3"))
            return bad_line(err, line, "a volume has NDims = 3");
    } else if (!strcmp(key, "DimSize")) {
        if (numbers(value, 3, h->dims))
            return bad_line(err, line, "DimSize is three whole numbers");
        h->have_dims = true;
    } else if (!strcmp(key, "ElementType")) {
        if (parse_type(value, &h->type))
            return bad_line(err, line, "ElementType is MET_UCHAR, MET_SHORT, MET_USHORT or MET_FLOAT");
        h->have_type = true;
    } else if (!strcmp(key, "ElementSpacing") || !strcmp(key, "ElementSize")) {
        if (numbers(value, 3, h->spacing))
            return bad_line(err, line, "ElementSpacing is three numbers");
        h->have_spacing = true;
        h->spacing_line = line;
    } else if (!strcmp(key, "Offset") || !strcmp(key, "Position") || !strcmp(key, "Origin")) {
        if (numbers(value, 3, h->origin))
            return bad_line(err, line, "Offset is three numbers");
        h->origin_line = line;
    } else if (!strcmp(key, "TransformMatrix") || !strcmp(key, "Rotation") || !strcmp(key, "Orientation")) {
        double m[9];
        if (numbers(value, 9, m) || m[0] != 1 || m[4] != 1 || m[8] != 1 || m[1] || m[2] || m[3] || m[5] || m[6] || m[7])
            return bad_line(err, line, "an oblique volume (TransformMatrix other than identity) is not read; resample it");
    } else if (!strcmp(key, "BinaryDataByteOrderMSB") || !strcmp(key, "ElementByteOrderMSB")) {
        h->big_endian = !strcasecmp(value, "True");
    } else if (!strcmp(key, "BinaryData")) {
        if (strcasecmp(value, "True"))
            return bad_line(err, line, "only binary data is read (BinaryData = True)");
    } else if (!strcmp(key, "CompressedData")) {
        h->compressed = !strcasecmp(value, "True");
    } else if (!strcmp(key, "ElementNumberOfChannels")) {
        if (strcmp(value, "1"))
            return bad_line(err, line, "one channel a sample");
    } else if (!strcmp(key, "HeaderSize")) {
        if (strcmp(value, "0"))
            return bad_line(err, line, "HeaderSize is not read");
    } else if (!strcmp(key, "ElementDataFile")) {
        if (h->detached && strcmp(value, "LOCAL"))
            h->data_file_line = line;
        else if (strcmp(value, "LOCAL"))
            return bad_line(err, line, "the samples must follow the header (ElementDataFile = LOCAL): post the .mha, or "
                                       "the .mhd and the file it names as two parts of multipart/form-data");
        return 1;
    }
    return 0;
}

/* A detached header's data file (volume_data_file): the line that names one ends the search. */
struct data_file {
    char *name;
    size_t cap;
    int line;
};

static int data_file_line(void *ctx, const char *key, const char *value, int line, struct sf_err *err)
{
    (void)err;
    struct data_file *d = ctx;
    if (strcmp(key, "data file") && strcmp(key, "datafile") && strcmp(key, "ElementDataFile"))
        return 0;
    if (strcmp(value, "LOCAL") && strncmp(value, "LIST", 4) && !strchr(value, '%') && strlen(value) < d->cap) {
        snprintf(d->name, d->cap, "%s", value);
        d->line = line;
    }
    return 1;
}

/* A detached header's text with a newline after its last line when it has none (editors leave it
 * off: header_lines reads whole lines); NULL when buf needs none, or is not text alone. */
#define DETACHED_MAX (HEADER_MAX_LINES << 10) /* header_lines' lines of under 1 KiB */

static char *terminated(const char *buf, size_t len)
{
    if (!len || buf[len - 1] == '\n' || len > DETACHED_MAX || memchr(buf, 0, len))
        return NULL;
    char *t = malloc(len + 1);
    if (t)
        memcpy(t, buf, len), t[len] = '\n';
    return t;
}

int volume_data_file(const char *buf, size_t len, char *name, size_t cap)
{
    bool nrrd = format_sniff_nrrd(buf, len), mha = format_sniff_mha(buf, len);
    struct data_file d = {name, cap, 0};
    size_t at;
    struct sf_err err = {0};
    char *t = nrrd || mha ? terminated(buf, len) : NULL;
    if (nrrd || mha) /* (a header that does not end before its data file line names none) */
        header_lines(t ? t : buf, t ? len + 1 : len, mha ? '=' : ':', mha, false, data_file_line, &d, &at, &err);
    free(t);
    return d.line;
}

/* The offset of the line after the one starting at `at` (len past the last). */
static size_t next_line(const char *buf, size_t len, size_t at)
{
    const char *nl = memchr(buf + at, '\n', len - at);
    return nl ? (size_t)(nl - buf) + 1 : len;
}

char *volume_attach(const char *hdr, size_t len, int line, const char *data, size_t data_len, size_t *out_len)
{
    size_t at = 0, end, rest_end;
    for (int l = 1; l < line; l++)
        at = next_line(hdr, len, at);
    end = rest_end = next_line(hdr, len, at);
    bool nrrd = format_sniff_nrrd(hdr, len); /* (else MetaImage, whose data file line is its last) */
    while (nrrd && rest_end < len && hdr[rest_end] != '\n' && hdr[rest_end] != '\r') /* to a blank line */
        rest_end = next_line(hdr, len, rest_end);
    bool open = rest_end > end && hdr[rest_end - 1] != '\n'; /* the last line without its newline */
    const char *tail = nrrd ? "\n" : "ElementDataFile = LOCAL\n";
    size_t rest = rest_end - end, tn = strlen(tail), n = at + rest + open + tn + data_len;
    char *whole = n < len ? NULL : malloc(n + 1); /* (n < len: the sizes wrapped) */
    if (!whole)
        return NULL;
    memcpy(whole, hdr, at);
    memcpy(whole + at, hdr + end, rest);
    if (open)
        whole[at + rest] = '\n';
    memcpy(whole + at + rest + open, tail, tn);
    memcpy(whole + at + rest + open + tn, data, data_len);
    whole[n] = 0;
    *out_len = n;
    return whole;
}

/* ---- the query ---- */

static int query_numbers(const char *options, const char *name, int n, double *out, bool *given, struct sf_err *err)
{
    char v[160], where[24];
    query_option(options, name, v, sizeof v);
    *given = v[0] != 0;
    snprintf(where, sizeof where, "?%s", name);
    if (*given && numbers(v, n, out))
        return sf_fail(err, SF_EINVAL, where, "%s is %d numbers separated by commas", name, n);
    return 0;
}

/* ?label=N (a whole number, not 0: the background) and ?labels=all, one or the other. */
static int label_options(const char *options, bool frep, struct volume *v, struct sf_err *err)
{
    char one[32], all[16];
    query_option(options, "label", one, sizeof one);
    query_option(options, "labels", all, sizeof all);
    if (one[0] && all[0])
        return sf_fail(err, SF_EINVAL, "?labels", "label=N and labels=all together: ask for one label's model, or for "
                       "every label's");
    if (all[0] && strcmp(all, "all"))
        return sf_fail(err, SF_EINVAL, "?labels", "labels is all (a model for every label of the map), not \"%.12s\"",
                       all);
    if (one[0]) {
        char *end;
        errno = 0;
        v->label = strtoll(one, &end, 10);
        if (end == one || *end || errno)
            return sf_fail(err, SF_EINVAL, "?label", "label is a whole number (a value of the label map), not \"%.20s\"",
                           one);
        if (v->label == 0)
            return sf_fail(err, SF_EINVAL, "?label", "0 is the background of a label map, not a label");
        v->has_label = true;
    }
    v->all_labels = all[0] != 0;
    if (frep && (v->has_label || v->all_labels))
        return sf_fail(err, SF_EINVAL, v->has_label ? "?label" : "?labels", "an FRep object is not a label map");
    return 0;
}

/* The options every format takes (iso, closed, name), and no unknown one. */
static int common_options(const char *options, bool frep, struct volume *v, struct sf_err *err)
{
    static const char *const KNOWN[] = {"iso", "closed", "name", "levels", "max_error", "features", "merge", "label",
                                        "labels", "dims", "type", "spacing", "origin", "format", "segment",
                                        "series" /* (the daemon's: the stored series the body was made of) */, NULL};
    for (const char *p = options ? options : ""; *p;) {
        size_t len = strcspn(p, "&"), key = strcspn(p, "=&");
        bool known = false;
        for (int k = 0; KNOWN[k] && !known; k++)
            known = strlen(KNOWN[k]) == key && !strncmp(p, KNOWN[k], key);
        if (!known) {
            char where[48];
            snprintf(where, sizeof where, "?%.*s", (int)(key < 40 ? key : 40), p);
            return sf_fail(err, SF_EINVAL, where, "unknown option \"%.*s\" (isosurfaces take iso, closed, name, "
                           "levels, max_error, features, merge, label, labels, for raw samples dims, type, spacing, "
                           "origin, and for a DICOM Segmentation segment)",
                           (int)(key < 40 ? key : 40), p);
        }
        p += len + (p[len] == '&');
    }
    char s[64], *end;
    int rc = label_options(options, frep, v, err);
    if (rc)
        return rc;
    query_option(options, "iso", s, sizeof s);
    if (s[0] && (v->has_label || v->all_labels))
        return sf_fail(err, SF_EINVAL, "?iso", "iso is implied by %s (a label's surface is its mask's at 0.5): leave "
                       "it out", v->has_label ? "label" : "labels");
    if (!s[0] && (frep || v->has_label || v->all_labels)) /* an FRep's surface is f = 0; a mask's 0.5 */
        snprintf(s, sizeof s, "%s", frep ? "0" : "0.5");
    v->iso = strtod(s, &end);
    if (!s[0])
        return sf_fail(err, SF_EINVAL, "?iso", "iso=V is required: the sample value the surface follows");
    if (end == s || *end || !isfinite(v->iso))
        return sf_fail(err, SF_EINVAL, "?iso", "iso is a finite number, not \"%s\"", s);
    if (!(fabs(v->iso) <= RANGE_MAX_ISO))
        return sf_fail(err, SF_EINVAL, "?iso", "iso is a number within %g of 0, not %g", RANGE_MAX_ISO, v->iso);
    query_option(options, "closed", s, sizeof s);
    if (s[0] && strcmp(s, "true") && strcmp(s, "false"))
        return sf_fail(err, SF_EINVAL, "?closed", "closed is true or false");
    v->closed = strcmp(s, "false") != 0;
    query_option(options, "name", v->name, sizeof v->name);
    query_option(options, "levels", s, sizeof s);
    v->levels = s[0] ? (int)strtol(s, &end, 10) : 1;
    if (s[0] && (*end || v->levels < 1 || v->levels > ISO_MAX_LEVELS))
        return sf_fail(err, SF_EINVAL, "?levels", "levels is a whole number from 1 to %d", ISO_MAX_LEVELS);
    query_option(options, "max_error", s, sizeof s);
    v->max_error = s[0] ? strtod(s, &end) : -1; /* -1: half the smallest spacing, once it is known */
    if (s[0] && (end == s || *end || !isfinite(v->max_error) || v->max_error < 0))
        return sf_fail(err, SF_EINVAL, "?max_error", "max_error is a length in mm, 0 or more");
    query_option(options, "features", s, sizeof s);
    if (s[0] && strcmp(s, "none") && strcmp(s, "sharp"))
        return sf_fail(err, SF_EINVAL, "?features", "features is none or sharp");
    v->sharp = !strcmp(s, "sharp");
    query_option(options, "merge", s, sizeof s);
    if (s[0] && strcmp(s, "cells") && strcmp(s, "pieces"))
        return sf_fail(err, SF_EINVAL, "?merge", "merge is cells or pieces");
    v->pieces = !strcmp(s, "pieces");
    if (v->pieces && v->sharp)
        return sf_fail(err, SF_EINVAL, "?merge", "merge=pieces draws no feature points (features=none)");
    if (v->all_labels && v->levels > 1)
        return sf_fail(err, SF_EINVAL, "?levels", "labels=all draws every cell at full resolution (levels=1)");
    if (v->all_labels && v->sharp)
        return sf_fail(err, SF_EINVAL, "?features", "labels=all draws no feature points (features=none)");
    return 0;
}

static int read_raw(const char *body, size_t len, const char *options, struct volume *v, struct sf_err *err)
{
    double d[3], sp[3] = {1, 1, 1}, org[3] = {0, 0, 0};
    bool given;
    int rc = query_numbers(options, "dims", 3, d, &given, err);
    if (rc)
        return rc;
    if (!given && (rc = input_refuse_foreign(body, len, IN_ISOSURFACE, "POST /isosurface", err)))
        return rc;
    if (!given)
        return sf_fail(err, SF_EINVAL, "?dims", "raw samples need dims=X,Y,Z (and type, spacing, origin): the body is "
                       "no other format read here by its first bytes (NRRD, MetaImage, NIfTI, DICOM, an FRep's JSON)");
    int dims[3];
    if ((rc = check_dims(d, "?dims", dims, err)))
        return rc;
    char t[32];
    query_option(options, "type", t, sizeof t);
    if (!t[0])
        return sf_fail(err, SF_EINVAL, "?type", "raw samples need type=uint8|int16|uint16|float32");
    if (parse_type(t, &v->g.type) || (strcmp(t, "uint8") && strcmp(t, "int16") && strcmp(t, "uint16") && strcmp(t, "float32")))
        return sf_fail(err, SF_EINVAL, "?type", "type is uint8, int16, uint16 or float32, not \"%.20s\"", t);
    v->integer = v->g.type != ISO_F32;
    if ((rc = query_numbers(options, "spacing", 3, sp, &given, err)) ||
        (rc = query_numbers(options, "origin", 3, org, &given, err)) ||
        (rc = check_samples(dims, org, sp, &(struct grid_fields){"?origin", "origin", "?spacing", "spacing", "?spacing"},
                            err)))
        return rc;
    v->g.nx = dims[0], v->g.ny = dims[1], v->g.nz = dims[2];
    memcpy(v->g.spacing, sp, sizeof sp);
    memcpy(v->g.origin, org, sizeof org);
    return place_samples(body, len, false, false, "?dims", v, err);
}

/* dims, type, spacing and origin in the query of a volume whose header gives them: refused. */
static int raw_only_options(const char *options, struct sf_err *err)
{
    char q[16];
    static const char *const RAW_ONLY[] = {"dims", "type", "spacing", "origin"};
    for (int k = 0; k < 4; k++) {
        query_option(options, RAW_ONLY[k], q, sizeof q);
        if (q[0]) {
            char where[16];
            snprintf(where, sizeof where, "?%s", RAW_ONLY[k]);
            return sf_fail(err, SF_EINVAL, where, "%s is for raw samples: this volume's header gives it", RAW_ONLY[k]);
        }
    }
    return 0;
}

/* An NRRD or MetaImage header and its samples: those after it in body, or with data (a detached
 * header's, read_pair) data's dlen bytes, named data_at in errors. */
static int read_header(const char *body, size_t len, const char *data, size_t dlen, const char *data_at, bool mha,
                       const char *options, struct volume *v, struct sf_err *err)
{
    int rc = raw_only_options(options, err);
    if (rc)
        return rc;
    struct header h = {.spacing = {1, 1, 1}, .detached = data != NULL};
    size_t at = 0;
    rc = header_lines(body, len, mha ? '=' : ':', mha, h.detached, mha ? mha_line : nrrd_line, &h, &at, err);
    for (int k = 0; !rc && k < h.n_seg; k++) /* the segments that give their label value name it */
        if (h.seg[k].has_value && !name_label(v, h.seg[k].value, h.seg[k].name, strlen(h.seg[k].name)))
            rc = sf_fail(err, SF_ENOMEM, "", "out of memory for the header's segments");
    free(h.seg);
    if (rc)
        return rc;
    if (h.detached && !h.data_file_line)
        return sf_fail(err, SF_EINVAL, "/parts", "the header part names no data file (%s): post a header with its "
                       "samples attached as the body alone", mha ? "ElementDataFile" : "data file");
    v->integer = h.have_type && h.type != ISO_F32;
    if (!h.have_dims || !h.have_type)
        return sf_fail(err, SF_EINVAL, "header", "the header gives no %s", h.have_dims ? mha ? "ElementType" : "type"
                                                                                       : mha ? "DimSize" : "sizes");
    int dims[3];
    char at_sp[32] = "header", at_org[32] = "header";
    if (h.spacing_line)
        snprintf(at_sp, sizeof at_sp, "header line %d", h.spacing_line);
    if (h.origin_line)
        snprintf(at_org, sizeof at_org, "header line %d", h.origin_line);
    struct grid_fields f = {at_org, mha ? "Offset" : "space origin", at_sp, mha ? "ElementSpacing" : "spacings", at_sp};
    if ((rc = check_dims(h.dims, "header", dims, err)) || (rc = check_samples(dims, h.origin, h.spacing, &f, err)))
        return rc;
    v->g.nx = dims[0], v->g.ny = dims[1], v->g.nz = dims[2];
    v->g.type = h.type;
    memcpy(v->g.spacing, h.spacing, sizeof h.spacing);
    memcpy(v->g.origin, h.origin, sizeof h.origin);
    return h.detached ? place_samples(data, dlen, h.compressed, h.big_endian, data_at, v, err)
                      : place_samples(body + at, len - at, h.compressed, h.big_endian, "data", v, err);
}

/* Which part of a multipart body is a detached header (an NRRD or MetaImage header naming a data
 * file), or -1; its data file's name into file. */
static int header_part(const struct part *parts, int n, char *file, size_t cap)
{
    for (int k = 0; k < n; k++)
        if ((format_sniff_nrrd(parts[k].data, parts[k].len) || format_sniff_mha(parts[k].data, parts[k].len)) &&
            volume_data_file(parts[k].data, parts[k].len, file, cap))
            return k;
    return -1;
}

/* "nrrd" or "mha" for a multipart body holding a detached header, else NULL. */
static const char *pair_format(const char *body, size_t len)
{
    struct part *parts;
    int n;
    char file[256];
    struct sf_err err = {0};
    if (!multipart_sniff(body, len) || multipart_split(body, len, &parts, &n, &err))
        return NULL;
    int h = header_part(parts, n, file, sizeof file);
    const char *format = h < 0 ? NULL : format_sniff_nrrd(parts[h].data, parts[h].len) ? "nrrd" : "mha";
    free(parts);
    return format;
}

/* A detached header and its data file as the two parts of a multipart/form-data body (curl -F
 * header=@CT.nhdr -F data=@CT.raw, in either order): the header's data file line names the other
 * part (its file name, where it has one, must be that file's, so that a wrong pairing is said, not
 * read), whose bytes are the samples, read in place as the attached header's are (volume_attach's
 * body, without copying the samples). */
static int read_pair(const char *body, size_t len, bool mha, const char *options, struct volume *v, struct sf_err *err)
{
    struct part *parts;
    int n, rc = multipart_split(body, len, &parts, &n, err);
    if (rc)
        return rc;
    char file[256], where[32];
    int h = header_part(parts, n, file, sizeof file);
    const char *base = strrchr(file, '/') ? strrchr(file, '/') + 1 : file;
    const struct part *d = n == 2 && h >= 0 ? &parts[1 - h] : NULL;
    snprintf(where, sizeof where, "/parts/%d", 1 - h);
    if (h < 0)
        rc = sf_fail(err, SF_EINVAL, "/parts", "no part is an NRRD or MetaImage header that names a data file");
    else if (!d)
        rc = sf_fail(err, SF_EINVAL, "/parts", "a detached header and its data file are two parts, not %d", n);
    else if (d->filename && (d->filename_len != strlen(base) || memcmp(d->filename, base, d->filename_len)))
        rc = sf_fail(err, SF_EINVAL, where, "the header names its data file %s, but this part is %.*s", base,
                     (int)(d->filename_len > 200 ? 200 : d->filename_len), d->filename);
    char *t = rc ? NULL : terminated(parts[h].data, parts[h].len);
    if (!rc)
        rc = read_header(t ? t : parts[h].data, t ? parts[h].len + 1 : parts[h].len, d->data, d->len, where, mha,
                         options, v, err);
    free(t);
    free(parts);
    return rc;
}

/* An FRep object: its grid is allocated here and sampled by volume_sample(). */
static int read_frep(const char *body, size_t len, const char *options, struct volume *v, struct sf_err *err)
{
    int rc = raw_only_options(options, err);
    if (rc)
        return rc;
    if (!(v->frep = malloc(sizeof *v->frep)))
        return sf_fail(err, SF_ENOMEM, "", "out of memory");
    if ((rc = frep_parse(body, len, v->frep, err))) {
        free(v->frep);
        v->frep = NULL;
        return rc;
    }
    struct frep_request *r = v->frep;
    v->g = (struct iso_grid){r->dims[0], r->dims[1], r->dims[2], ISO_F32, NULL, {r->cell, r->cell, r->cell},
                             {r->lo[0], r->lo[1], r->lo[2]}};
    if ((rc = check_grid(r->lo, r->hi, v->g.spacing, &(struct grid_fields){"/bounds/0", "bounds", "/cell", "cell", "/bounds/1"},
                         err)))
        return rc;
    if (!v->name[0])
        snprintf(v->name, sizeof v->name, "%s", r->name);
    if (v->check_only)
        return 0;
    if (!(v->owned = malloc(sizeof(float) * r->dims[0] * r->dims[1] * r->dims[2])))
        return sf_fail(err, SF_ENOMEM, "/cell", "no memory for a grid of %d x %d x %d samples", r->dims[0],
                       r->dims[1], r->dims[2]);
    v->g.samples = v->owned;
    return 0;
}

int volume_mesh_empty(const struct volume *v, const struct trimesh *m, struct sf_err *err)
{
    if (m->n_tri)
        return 0;
    if (v->frep)
        return sf_fail(err, SF_EINVAL, "/bounds", "the object has no surface inside its bounds");
    return sf_fail(err, SF_EINVAL, "?iso", "no surface at iso %g: every sample is on one side of it", v->iso);
}

static double frep_field(const void *ctx, const double p[3], double g[3])
{
    return frep_eval(&((const struct frep_request *)ctx)->f, p, g);
}

struct iso_opts volume_iso_opts(const struct volume *v)
{
    struct iso_opts o = {.iso = v->iso, .closed = v->closed, .normals = true, .sharp = v->sharp, .pieces = v->pieces};
    if (v->sharp && v->frep)
        o.field = frep_field, o.field_ctx = v->frep;
    return o;
}

bool volume_adaptive(const struct volume *v) { return v->levels > 1 || v->sharp; }

int volume_sample(struct volume *v, int z0, int z1, const struct sf_progress *pr, struct sf_err *err)
{
    return v->frep ? frep_sample(&v->frep->f, v->g.origin, v->frep->cell, v->g.nx, v->g.ny, z0, z1, v->owned, pr, err)
                   : 0;
}

/* A DICOM series as multipart/form-data, or one DICOM file (a multi-frame image). */
/* v's grid in range as it lies in patient coordinates: its box corner to corner along its axes (an
 * oblique one's turned), its spacings. */
static int check_turned_grid(struct volume *v, const struct grid_fields *f, struct sf_err *err)
{
    for (int a = 0; a < 3; a++)
        for (int b = 0; b < 3; b++)
            v->oblique = v->oblique || fabs(v->axes[a][b] - (a == b)) > 1e-9;
    double lo[3], hi[3], steps[3] = {v->g.nx - 1, v->g.ny - 1, v->g.nz - 1};
    for (int b = 0; b < 3; b++) {
        lo[b] = hi[b] = v->g.origin[b];
        for (int a = 0; a < 3; a++) {
            double d = steps[a] * v->g.spacing[a] * v->axes[a][b];
            lo[b] += fmin(d, 0), hi[b] += fmax(d, 0);
        }
    }
    return check_grid(lo, hi, v->g.spacing, f, err);
}

static int read_series(const char *body, size_t len, const char *options, struct volume *v, struct sf_err *err)
{
    int rc = raw_only_options(options, err);
    if (rc)
        return rc;
    char q[16], *end;
    query_option(options, "segment", q, sizeof q);
    long segment = q[0] ? strtol(q, &end, 10) : 0;
    if (q[0] && (*end || segment < 1 || segment > 65535))
        return sf_fail(err, SF_EINVAL, "?segment", "segment is a SegmentNumber, a whole number from 1 to 65535");
    /* a Segmentation as a label map: ?label=N its segment N, ?labels=all every segment */
    bool as_labels = v->has_label || v->all_labels;
    if (as_labels && q[0])
        return sf_fail(err, SF_EINVAL, "?segment", "segment and %s together: a Segmentation's label is its segment "
                       "(?label=N reads segment N as a label map's label, ?segment=N as it is, fractions kept)",
                       v->has_label ? "label" : "labels");
    if (v->has_label && (v->label < 1 || v->label > 65535))
        return sf_fail(err, SF_EINVAL, "?label", "a Segmentation's labels are its SegmentNumbers, 1 to 65535");
    if (v->has_label)
        segment = (long)v->label;
    struct part one = {body, len, NULL, 0}, *parts = &one;
    int n = 1;
    /* a multipart series, or one DICOM file as the body: a series of that one part, /parts/0 */
    if (multipart_sniff(body, len) && (rc = multipart_split(body, len, &parts, &n, err)))
        return rc;
    struct series s;
    rc = series_read(parts, n, v->check_only, VOLUME_MAX_SAMPLES, (int)segment, as_labels, &s, err);
    if (parts != &one)
        free(parts);
    if (rc && v->has_label && !strcmp(err->pointer, "?segment")) /* (the segment chosen was ?label) */
        snprintf(err->pointer, sizeof err->pointer, "?label");
    if (rc)
        return rc;
    v->g = s.g;
    v->owned = s.owned;
    v->integer = s.label_map;
    for (int k = 0; k < s.n_segments && k < 2 * VOLUME_MAX_LABELS && !rc; k++) /* (past them labels=all refuses) */
        if (s.segments[k].label[0] && !name_label(v, s.segments[k].number, s.segments[k].label,
                                                  strlen(s.segments[k].label)))
            rc = sf_fail(err, SF_ENOMEM, "", "out of memory for the segments' names");
    free(s.segments);
    if (rc)
        return rc;
    if (v->check_only && !s.typed) /* int16 or float32 is decided by the samples' rescaled values: the wider until then */
        v->g.type = ISO_F32;
    memcpy(v->axes, s.axes, sizeof s.axes);
    memcpy(v->series_uid, s.series_uid, sizeof v->series_uid);
    memcpy(v->study_uid, s.study_uid, sizeof v->study_uid);
    memcpy(v->frame_uid, s.frame_uid, sizeof v->frame_uid);
    /* the reader kept each slice's position in range; here the grid's box */
    return check_turned_grid(v, &(struct grid_fields){"/parts", "ImagePositionPatient", "/parts",
                             "the spacing (PixelSpacing, between slices)", "/parts"}, err);
}

/* Reverses axis a of v's grid (its samples are to be read so): the origin moves to its far end. */
static void reverse_axis(struct volume *v, int a, const int n[3])
{
    for (int b = 0; b < 3; b++) {
        v->g.origin[b] += (n[a] - 1) * v->g.spacing[a] * v->axes[a][b];
        v->axes[a][b] = -v->axes[a][b];
    }
}

/* The grid a NIfTI header's affine gives, in patient coordinates (DICOM's LPS: the RAS affine's x
 * and y rows negated): spacings the columns' lengths, axes their directions, at right angles.
 * Axes along the patient's own but reversed (the RAS files' usual LPS diag(-1, -1, 1), LAS, ...)
 * are read reversed (flip[a]), so that the grid is not turned at all; a turned left-handed one has
 * its x reversed, so that the mesh faces out. */
static int nifti_grid(const struct nifti_header *h, struct volume *v, bool flip[3], struct sf_err *err)
{
    double sign[3] = {-1, -1, 1};
    for (int a = 0; a < 3; a++) {
        double c[3], n = 0;
        for (int b = 0; b < 3; b++)
            c[b] = sign[b] * h->affine[b][a], n += c[b] * c[b];
        v->g.spacing[a] = sqrt(n);
        if (!(v->g.spacing[a] > 0))
            return sf_fail(err, SF_EINVAL, "header", "the %s's column %d is zero: its voxels have no size along an axis",
                           h->xform, a);
        for (int b = 0; b < 3; b++)
            v->axes[a][b] = c[b] / v->g.spacing[a];
        v->g.origin[a] = sign[a] * h->affine[a][3];
    }
    for (int a = 0; a < 3; a++)
        for (int b = a + 1; b < 3; b++) {
            double dot = v->axes[a][0] * v->axes[b][0] + v->axes[a][1] * v->axes[b][1] + v->axes[a][2] * v->axes[b][2];
            if (fabs(dot) > 1e-4)
                return sf_fail(err, SF_EINVAL, "header", "the %s shears the grid (its axes %d and %d are %.2f degrees "
                               "apart, not 90): surfd meshes grids whose axes are at right angles", h->xform, a, b,
                               acos(fmax(-1, fmin(1, dot))) * 180 / M_PI);
        }
    const int n[3] = {v->g.nx, v->g.ny, v->g.nz};
    bool along = true; /* each axis along the patient's own, either way */
    for (int a = 0; a < 3; a++)
        along = along && fabs(fabs(v->axes[a][a]) - 1) < 1e-9;
    for (int a = 0; a < 3; a++)
        if ((flip[a] = along && v->axes[a][a] < 0))
            reverse_axis(v, a, n);
    const double(*x)[3] = (const double(*)[3])v->axes;
    double det = x[0][0] * (x[1][1] * x[2][2] - x[1][2] * x[2][1]) - x[0][1] * (x[1][0] * x[2][2] - x[1][2] * x[2][0]) +
                 x[0][2] * (x[1][0] * x[2][1] - x[1][1] * x[2][0]);
    if (det < 0) {
        flip[0] = !flip[0];
        reverse_axis(v, 0, n);
    }
    return check_turned_grid(v, &(struct grid_fields){"header", h->xform, "header", "the voxel size", "header"}, err);
}

/* A NIfTI sample k of datatype (bytes each, swapped or not) as a double. */
static double nifti_value(const unsigned char *p, int datatype, int bytes, bool swap)
{
    unsigned char b[8];
    for (int k = 0; k < bytes; k++)
        b[k] = p[swap ? bytes - 1 - k : k];
    int8_t i8; int16_t i16; uint16_t u16; int32_t i32; uint32_t u32; float f; double d;
    switch (datatype) {
    case 2: return b[0];
    case 256: memcpy(&i8, b, 1); return i8;
    case 4: memcpy(&i16, b, 2); return i16;
    case 512: memcpy(&u16, b, 2); return u16;
    case 8: memcpy(&i32, b, 4); return i32;
    case 768: memcpy(&u32, b, 4); return u32;
    case 16: memcpy(&f, b, 4); return f;
    default: memcpy(&d, b, 8); return d;
    }
}

/* The greatest label a float32 sample holds exactly (a NIfTI's int32 and uint32 are read so). */
#define LABEL_MAX_F32 16777216.0

/* A label the file's label table names (nifti_label_table's fn). */
static void nifti_name(void *ctx, long long value, const char *name, size_t n)
{
    struct volume *v = ctx;
    if (v->n_named < 2 * VOLUME_MAX_LABELS)
        name_label(v, value, name, n);
}

/* A NIfTI-1 or NIfTI-2 single file, gzip or not (nifti.h), in patient coordinates (nifti_grid).
 * Samples of a type core/iso has a grid of (uint8, int16, uint16, float32), unscaled, are used as
 * they are (in place when they can be); others, scaled ones (scl_slope: iso is in the scaled
 * values), swapped or reversed ones are written anew, float32 unless only their order changes. */
static int read_nifti(const char *body, size_t len, const char *options, struct volume *v, struct sf_err *err)
{
    int rc = raw_only_options(options, err);
    if (rc)
        return rc;
    bool gz = len >= 2 && (unsigned char)body[0] == 0x1f && (unsigned char)body[1] == 0x8b;
    unsigned char head[NIFTI_HEADER_MAX];
    size_t hn = len;
    const unsigned char *hb = (const unsigned char *)body;
    if (gz && (rc = nifti_inflate_head(body, len, head, sizeof head, &hn, err)))
        return rc;
    struct nifti_header h;
    if ((rc = nifti_header(gz ? head : hb, hn, &h, err)))
        return rc;
    int dims[3];
    bool flip[3] = {false, false, false};
    if ((rc = check_dims((const double[3]){(double)h.dims[0], (double)h.dims[1], (double)h.dims[2]}, "header", dims, err)))
        return rc;
    v->g.nx = dims[0], v->g.ny = dims[1], v->g.nz = dims[2];
    if ((rc = nifti_grid(&h, v, flip, err)))
        return rc;
    static const struct { int datatype; enum iso_type type; } NATIVE[] = {{2, ISO_U8}, {4, ISO_I16}, {512, ISO_U16},
                                                                          {16, ISO_F32}};
    bool scaled = h.slope != 0 && (h.slope != 1 || h.inter != 0), native = false;
    bool labels = v->has_label || v->all_labels;
    v->integer = !scaled && h.datatype != 16 && h.datatype != 64;
    if (labels)
        snprintf(v->map_name, sizeof v->map_name, "%s", h.intent_name);
    v->g.type = ISO_F32;
    for (size_t k = 0; k < sizeof NATIVE / sizeof *NATIVE && !scaled; k++)
        if (NATIVE[k].datatype == h.datatype)
            v->g.type = NATIVE[k].type, native = true;
    size_t count = (size_t)dims[0] * (size_t)dims[1] * (size_t)dims[2], bytes = count * (size_t)h.bytes;
    if ((uint64_t)h.vox_offset > (uint64_t)(SIZE_MAX - bytes))
        return sf_fail(err, SF_EINVAL, "header", "vox_offset %lld is past any file", (long long)h.vox_offset);
    size_t need = (size_t)h.vox_offset + bytes;
    if (!gz && len != need)
        return sf_fail(err, SF_EINVAL, "data", "the file holds %zu bytes; its header makes %zu (vox_offset and dims x "
                       "datatype)", len, need);
    if (v->check_only)
        return 0;
    void *whole = NULL;
    if (gz && (rc = inflate_all(body, len, need, &whole, err)))
        return rc;
    const unsigned char *data = (const unsigned char *)(gz ? whole : body) + h.vox_offset;
    if (labels && nifti_label_table(data - h.vox_offset, need, &h, nifti_name, v) > 2 * VOLUME_MAX_LABELS) {
        free(whole);
        return sf_fail(err, SF_EINVAL, "header", "its label table names over %d labels", 2 * VOLUME_MAX_LABELS);
    }
    size_t ts = type_size(v->g.type);
    if (native && !flip[0] && !flip[1] && !flip[2] && !h.big_endian && (uintptr_t)data % ts == 0) { /* as it is */
        v->owned = whole;
        v->g.samples = data;
    } else {
        unsigned char *out = malloc(count * ts);
        if (!out) {
            free(whole);
            return sf_fail(err, SF_ENOMEM, "", "out of memory for %zu samples", count);
        }
        for (size_t i = 0; i < count; i++) {
            size_t c[3] = {i % (size_t)dims[0], i / (size_t)dims[0] % (size_t)dims[1], i / ((size_t)dims[0] * dims[1])};
            for (int a = 0; a < 3; a++)
                c[a] = flip[a] ? (size_t)dims[a] - 1 - c[a] : c[a];
            size_t src = c[0] + (size_t)dims[0] * (c[1] + (size_t)dims[1] * c[2]);
            const unsigned char *p = data + src * (size_t)h.bytes;
            if (native && !h.big_endian) {
                memcpy(out + i * ts, p, ts);
            } else {
                double val = nifti_value(p, h.datatype, h.bytes, h.big_endian);
                if (scaled)
                    val = h.slope * val + h.inter;
                if (labels && v->integer && fabs(val) > LABEL_MAX_F32) { /* (int32 and uint32: read as float32) */
                    free(whole);
                    free(out);
                    return sf_fail(err, SF_EINVAL, "data", "sample %zu is label %.0f: labels are read up to %.0f either "
                                   "side of 0", i, val, LABEL_MAX_F32);
                }
                if (v->g.type == ISO_F32) {
                    float fv = (float)val;
                    memcpy(out + i * ts, &fv, ts);
                } else if (v->g.type == ISO_I16) {
                    int16_t s16 = (int16_t)val;
                    memcpy(out + i * ts, &s16, ts);
                } else if (v->g.type == ISO_U16) {
                    uint16_t s16 = (uint16_t)val;
                    memcpy(out + i * ts, &s16, ts);
                } else {
                    out[i] = (unsigned char)val;
                }
            }
        }
        free(whole);
        v->owned = out;
        v->g.samples = out;
    }
    return finite_samples(v, "data", err);
}

/* ?iso within what the samples' type can hold (a DICOM series' after its rescale: int16 when its
 * values fit, float32 else): past it every sample is on one side, which is said before any work. */
static int check_iso_reach(const struct volume *v, struct sf_err *err)
{
    static const struct type_reach {
        const char *name;
        double lo, hi;
    } REACH[] = {[ISO_U8] = {"uint8", 0, 255}, [ISO_I16] = {"int16", -32768, 32767}, [ISO_U16] = {"uint16", 0, 65535},
                 [ISO_F32] = {"float32", -RANGE_MAX_ISO, RANGE_MAX_ISO}};
    const struct type_reach *r = &REACH[v->g.type];
    if (v->iso >= r->lo && v->iso <= r->hi)
        return 0;
    return sf_fail(err, SF_EINVAL, "?iso", "iso %g is past what the volume's %s samples hold (%g to %g): every sample "
                   "would be on one side of it", v->iso, r->name, r->lo, r->hi);
}

/* ---- label maps ---- */

static const char *type_name(enum iso_type t)
{
    return t == ISO_U8 ? "uint8" : t == ISO_I16 ? "int16" : t == ISO_U16 ? "uint16" : "float32";
}

/* Sample i of v's grid as a whole number: 0, or SF_EINVAL at "data" for a float32 sample that is
 * not one (a label map's are). */
static int label_at(const struct iso_grid *g, size_t i, long long *out, struct sf_err *err)
{
    switch (g->type) {
    case ISO_U8: *out = ((const uint8_t *)g->samples)[i]; return 0;
    case ISO_I16: *out = ((const int16_t *)g->samples)[i]; return 0;
    case ISO_U16: *out = ((const uint16_t *)g->samples)[i]; return 0;
    default: break;
    }
    float f = ((const float *)g->samples)[i];
    if (f != floorf(f) || fabsf(f) > (float)LABEL_MAX_F32)
        return sf_fail(err, SF_EINVAL, "data", "sample %zu is %g: a label map's samples are whole numbers", i, (double)f);
    *out = (long long)f;
    return 0;
}

static int cmp_ll(const void *a, const void *b)
{
    long long x = *(const long long *)a, y = *(const long long *)b;
    return (x > y) - (x < y);
}

/* The map's labels (its values but 0), increasing, into vals (room for cap + 1): their number,
 * cap + 1 when there are more; or SF_EINVAL, SF_ENOMEM. Integer types by a table of their values,
 * float32 (a NIfTI's int32) by a hash set of cap + 1 at most. */
static int distinct_labels(const struct iso_grid *g, long long *vals, int cap, struct sf_err *err)
{
    size_t count = (size_t)g->nx * (size_t)g->ny * (size_t)g->nz;
    int n = 0;
    if (g->type != ISO_F32) {
        uint8_t *seen = calloc(65536, 1);
        if (!seen)
            return sf_fail(err, SF_ENOMEM, "", "out of memory for the map's labels");
        long long value, off = g->type == ISO_I16 ? 32768 : 0;
        for (size_t i = 0; i < count; i++) {
            label_at(g, i, &value, err);
            seen[value + off] = 1;
        }
        for (long long k = 0; k < 65536 && n <= cap; k++)
            if (seen[k] && k - off != 0)
                vals[n++] = k - off;
        free(seen);
        return n;
    }
    size_t slots = 1;
    while (slots < 2 * ((size_t)cap + 1))
        slots *= 2;
    long long *set = malloc(sizeof *set * slots);
    bool *used = calloc(slots, 1);
    if (!set || !used) {
        free(set), free(used);
        return sf_fail(err, SF_ENOMEM, "", "out of memory for the map's labels");
    }
    int rc = 0;
    for (size_t i = 0; i < count && n <= cap && !rc; i++) {
        long long value;
        if ((rc = label_at(g, i, &value, err)) || value == 0)
            continue;
        size_t h = (size_t)((unsigned long long)value * 0x9e3779b97f4a7c15ull >> 20) & (slots - 1);
        while (used[h] && set[h] != value)
            h = (h + 1) & (slots - 1);
        if (!used[h])
            used[h] = true, set[h] = value, vals[n++] = value;
    }
    free(set), free(used);
    if (!rc)
        qsort(vals, (size_t)n, sizeof *vals, cmp_ll);
    return rc ? rc : n;
}

/* Label value's name: the file's (the last it gives), "NAME N" after a NIfTI's intent_name, else
 * "label N". */
static void label_named(const struct volume *v, long long value, char name[VOLUME_LABEL_NAME])
{
    for (int k = v->n_named - 1; k >= 0; k--)
        if (v->named[k].value == value && v->named[k].name[0]) {
            snprintf(name, VOLUME_LABEL_NAME, "%s", v->named[k].name);
            return;
        }
    if (v->map_name[0])
        snprintf(name, VOLUME_LABEL_NAME, "%s %lld", v->map_name, value);
    else
        snprintf(name, VOLUME_LABEL_NAME, "label %lld", value);
}

void volume_label_name(const struct volume *v, int k, char *out, size_t cap)
{
    const char *own = k >= 1 && k <= v->n_labels ? v->label_of[k - 1].name : "";
    if (v->name[0] && v->all_labels)
        snprintf(out, cap, "%s %s", v->name, own);
    else
        snprintf(out, cap, "%s", v->name[0] ? v->name : own);
}

/* The map's labels listed for a message: "1, 2, 5 and 7" (the first 12). */
static void list_labels(const long long *vals, int n, int cap, char *out, size_t size)
{
    size_t at = 0;
    out[0] = 0;
    for (int k = 0; k < n && k < 12 && at < size; k++)
        at += (size_t)snprintf(out + at, size - at, "%s%lld", k == 0 ? "" : k + 1 == n ? " and " : ", ", vals[k]);
    if ((n > 12 || n > cap) && at < size)
        snprintf(out + at, size - at, " and more");
}

/* v's samples made N's mask (?label=N) or label indices (?labels=all), iso 0.5; the labels found
 * into v->label_of. With check_only, what the header says: an integer type that holds N. */
static int label_grid(struct volume *v, const char *format, struct sf_err *err)
{
    const char *at = v->has_label ? "?label" : "?labels";
    if (!strcmp(format, "dicom") && !v->integer)
        return sf_fail(err, SF_EINVAL, at, "a DICOM image series is not a label map (label maps are integer NRRD, "
                       "MetaImage, NIfTI or raw samples, or a DICOM Segmentation)");
    if (!v->integer)
        return sf_fail(err, SF_EINVAL, at, "a label map's samples are whole numbers: this volume's are %s", v->check_only &&
                       v->g.type == ISO_F32 ? "float" : "scaled or float");
    double lo = v->g.type == ISO_U8 || v->g.type == ISO_U16 ? 0 : v->g.type == ISO_I16 ? -32768 : -LABEL_MAX_F32,
           hi = v->g.type == ISO_U8 ? 255 : v->g.type == ISO_I16 ? 32767 : v->g.type == ISO_U16 ? 65535 : LABEL_MAX_F32;
    if (v->has_label && ((double)v->label < lo || (double)v->label > hi))
        return sf_fail(err, SF_EINVAL, "?label", "label %lld is not in the map: its %s samples hold %.0f to %.0f",
                       v->label, v->g.type == ISO_F32 ? "integer" : type_name(v->g.type), lo, hi);
    if (v->check_only)
        return 0;
    long long *vals = malloc(sizeof *vals * (VOLUME_MAX_LABELS + 1));
    if (!vals)
        return sf_fail(err, SF_ENOMEM, "", "out of memory for the map's labels");
    int n = distinct_labels(&v->g, vals, VOLUME_MAX_LABELS, err), rc = n < 0 ? n : 0, index = 0;
    char list[200];
    if (!rc && n == 0)
        rc = sf_fail(err, SF_EINVAL, at, "the map has no label: every sample is 0 (the background)");
    if (!rc && v->has_label) {
        while (index < n && vals[index] != v->label)
            index++;
        list_labels(vals, n, VOLUME_MAX_LABELS, list, sizeof list);
        if (index == n && n <= VOLUME_MAX_LABELS) /* (over the cap, the list may not hold it: its samples say) */
            rc = sf_fail(err, SF_EINVAL, "?label", "label %lld is not in the map; its labels are %s", v->label, list);
    }
    if (!rc && v->all_labels && n > VOLUME_MAX_LABELS)
        rc = sf_fail(err, SF_ELIMIT, "?labels", "the map has over %d labels: labels=all makes a model of each of at most "
                     "%d", VOLUME_MAX_LABELS, VOLUME_MAX_LABELS);
    size_t count = (size_t)v->g.nx * (size_t)v->g.ny * (size_t)v->g.nz;
    int n_out = v->has_label ? 1 : n;
    bool wide = n_out > 255;
    void *grid = rc ? NULL : malloc(count * (wide ? 2 : 1));
    v->label_of = rc ? NULL : calloc((size_t)n_out, sizeof *v->label_of);
    if (!rc && (!grid || !v->label_of))
        rc = sf_fail(err, SF_ENOMEM, "", "out of memory for the map's %zu labels", count);
    uint16_t *table = NULL; /* integer types: value (int16's + 32768) to index */
    long long off = v->g.type == ISO_I16 ? 32768 : 0;
    if (!rc && v->all_labels && v->g.type != ISO_F32 && !(table = calloc(65536, sizeof *table)))
        rc = sf_fail(err, SF_ENOMEM, "", "out of memory for the map's labels");
    for (int k = 0; !rc && table && k < n; k++)
        table[vals[k] + off] = (uint16_t)(k + 1);
    for (size_t i = 0; !rc && i < count; i++) {
        long long value;
        label_at(&v->g, i, &value, err);
        int k = 0;
        if (v->has_label)
            k = value == v->label;
        else if (table)
            k = table[value + off];
        else if (value) {
            const long long *hit = bsearch(&value, vals, (size_t)n, sizeof *vals, cmp_ll);
            k = (int)(hit - vals) + 1;
        }
        if (wide)
            ((uint16_t *)grid)[i] = (uint16_t)k;
        else
            ((uint8_t *)grid)[i] = (uint8_t)k;
    }
    free(table);
    if (!rc) {
        v->n_labels = n_out;
        for (int k = 0; k < n_out; k++) {
            v->label_of[k].value = v->has_label ? v->label : vals[k];
            label_named(v, v->label_of[k].value, v->label_of[k].name);
        }
        if (v->has_label && !v->name[0])
            snprintf(v->name, sizeof v->name, "%s", v->label_of[0].name);
        free(v->owned);
        v->owned = grid;
        v->g.samples = grid;
        v->map_type = v->g.type;
        v->g.type = wide ? ISO_U16 : ISO_U8;
        v->iso = 0.5;
    } else {
        free(grid);
    }
    free(vals);
    return rc;
}

static int read_volume(const char *body, size_t len, const char *format, const char *options, bool check_only,
                       struct volume *v, struct sf_err *err)
{
    memset(v, 0, sizeof *v);
    v->check_only = check_only;
    format = volume_format_of(body, len, format, options);
    v->source = strcmp(format, "frep") ? "isosurface" : "frep";
    int rc = common_options(options, !strcmp(format, "frep"), v, err);
    if (rc)
        return rc;
    bool nrrd = format_sniff_nrrd(body, len), mha = format_sniff_mha(body, len), nifti = nifti_sniff_body(body, len);
    for (int a = 0; a < 3; a++)
        v->axes[a][a] = 1;
    char segment[8];
    query_option(options, "segment", segment, sizeof segment);
    if (segment[0] && strcmp(format, "dicom"))
        return sf_fail(err, SF_EINVAL, "?segment", "segment chooses a segment of a DICOM Segmentation: this body is "
                       "not DICOM");
    if ((!strcmp(format, "nrrd") || !strcmp(format, "mha")) && multipart_sniff(body, len)) {
        rc = read_pair(body, len, !strcmp(format, "mha"), options, v, err);
    } else if (!strcmp(format, "nrrd")) {
        if (!nrrd)
            return sf_fail(err, SF_EFORMAT, "header", "an NRRD file starts with \"NRRD000x\"");
        rc = read_header(body, len, NULL, 0, NULL, false, options, v, err);
    } else if (!strcmp(format, "mha")) {
        if (!mha)
            return sf_fail(err, SF_EFORMAT, "header", "a MetaImage header starts with ObjectType or NDims");
        rc = read_header(body, len, NULL, 0, NULL, true, options, v, err);
    } else if (!strcmp(format, "nifti")) {
        if (!nifti)
            return sf_fail(err, SF_EFORMAT, "header", "a NIfTI file begins with its header (sizeof_hdr 348 or 540), "
                           "or is the gzip of one");
        rc = read_nifti(body, len, options, v, err);
    } else if (!strcmp(format, "raw")) {
        rc = read_raw(body, len, options, v, err);
    } else if (!strcmp(format, "dicom")) {
        rc = read_series(body, len, options, v, err);
    } else if (!strcmp(format, "frep")) {
        rc = read_frep(body, len, options, v, err);
    } else {
        rc = sf_fail(err, SF_EFORMAT, "?format", "format is raw, nrrd, mha, nifti, dicom or frep");
    }
    if (!rc && (v->has_label || v->all_labels))
        rc = label_grid(v, format, err);
    if (!rc)
        rc = check_iso_reach(v, err);
    if (!rc && v->max_error < 0)
        v->max_error = 0.5 * fmin(v->g.spacing[0], fmin(v->g.spacing[1], v->g.spacing[2]));
    if (!rc && volume_adaptive(v) && (double)v->g.nx * v->g.ny * v->g.nz > ISO_ADAPT_MAX_SAMPLES)
        rc = sf_fail(err, SF_ELIMIT, v->levels > 1 ? "?levels" : "?features", "levels over 1 and features=sharp take "
                     "volumes of at most %u samples (this one has %.0f): send levels=1 without features, or a cropped "
                     "or resampled volume", ISO_ADAPT_MAX_SAMPLES, (double)v->g.nx * v->g.ny * v->g.nz);
    if (rc)
        volume_free(v);
    return rc;
}

int volume_read(const char *body, size_t len, const char *format, const char *options, struct volume *v,
                struct sf_err *err)
{
    return read_volume(body, len, format, options, false, v, err);
}

int volume_check(const char *body, size_t len, const char *format, const char *options, int max_labels,
                 struct sf_err *err)
{
    struct volume v;
    int rc = read_volume(body, len, format, options, true, &v, err);
    int named = 0, cap = max_labels > 0 && max_labels < VOLUME_MAX_LABELS ? max_labels : VOLUME_MAX_LABELS;
    long long *vals = !rc && v.all_labels && v.n_named ? malloc(sizeof *vals * (size_t)v.n_named) : NULL;
    for (int k = 0; vals && k < v.n_named; k++)
        vals[k] = v.named[k].value;
    if (vals) /* the distinct values named but 0 */
        qsort(vals, (size_t)v.n_named, sizeof *vals, cmp_ll);
    for (int k = 0; vals && k < v.n_named; k++)
        named += vals[k] != 0 && (k == 0 || vals[k] != vals[k - 1]);
    free(vals);
    if (!rc && named > cap)
        rc = sf_fail(err, SF_ELIMIT, "?labels", "the header names %d labels; labels=all makes %d models a request at "
                     "most%s", named, cap, cap < VOLUME_MAX_LABELS ? " on this node (max-labels)" : "");
    volume_free(&v);
    return rc;
}

void volume_free(struct volume *v)
{
    free(v->label_of);
    free(v->named);
    v->label_of = v->named = NULL;
    v->n_labels = v->n_named = v->cap_named = 0;
    volume_drop_samples(v);
}

void volume_drop_samples(struct volume *v)
{
    if (v->frep)
        frep_request_free(v->frep);
    free(v->frep);
    v->frep = NULL;
    free(v->owned);
    v->owned = NULL;
    v->g.samples = NULL;
}

int volume_region(const char *options, const struct iso_grid *g, size_t len, int lo[3], int n[3], struct sf_err *err)
{
    char value[128];
    double r[6];
    query_option(options, "region", value, sizeof value);
    if (!value[0])
        return sf_fail(err, SF_EINVAL, "?region", "region=x0,y0,z0,nx,ny,nz names the block of samples the body holds");
    if (numbers(value, 6, r))
        return sf_fail(err, SF_EINVAL, "?region", "region is six whole numbers x0,y0,z0,nx,ny,nz");
    int dims[3] = {g->nx, g->ny, g->nz};
    for (int d = 0; d < 3; d++) {
        if (r[d] != floor(r[d]) || r[d + 3] != floor(r[d + 3]) || r[d] < 0 || r[d + 3] < 1 ||
            r[d] + r[d + 3] > dims[d])
            return sf_fail(err, SF_EINVAL, "?region", "the region must lie in the volume's %d x %d x %d samples",
                           g->nx, g->ny, g->nz);
        lo[d] = (int)r[d], n[d] = (int)r[d + 3];
    }
    size_t want = (size_t)n[0] * n[1] * n[2] * type_size(g->type);
    if (len != want)
        return sf_fail(err, SF_EINVAL, "", "the body holds %zu bytes, but the region's %d x %d x %d samples of the "
                       "volume's type make %zu", len, n[0], n[1], n[2], want);
    return 0;
}
