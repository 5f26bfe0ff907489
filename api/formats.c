/* formats.c - the table of input formats (formats.h) and the magic that knows each. */
#include "formats.h"

#include <ctype.h>
#include <jansson.h>
#include <stdio.h>
#include <string.h>
#include <strings.h>

#include "dicom_scan.h"
#include "nifti.h"

/* ---- magic ---- */

static size_t skip_space(const char *buf, size_t len, size_t at)
{
    while (at < len && isspace((unsigned char)buf[at]))
        at++;
    return at;
}

/* A JSON object or array (a scene may be a bare list of patches), and no control bytes before. */
static bool sniff_json(const char *buf, size_t len)
{
    size_t at = skip_space(buf, len, 0);
    return at < len && (buf[at] == '{' || buf[at] == '[');
}

bool format_sniff_json_object(const char *buf, size_t len)
{
    size_t at = 0;
    for (size_t k = 0; k < len && k < 64; k++)
        if ((unsigned char)buf[k] < 0x20 && !strchr(" \t\r\n", buf[k]))
            return false;
    at = skip_space(buf, len, 0);
    if (at >= len || buf[at++] != '{')
        return false;
    at = skip_space(buf, len, at);
    return at < len && (buf[at] == '"' || buf[at] == '}');
}

/* IGES: the Start section's letter in column 73 of the first line. */
static bool sniff_iges(const char *buf, size_t len)
{
    const char *nl = memchr(buf, '\n', len);
    size_t first = nl ? (size_t)(nl - buf) : len;
    return first >= 73 && buf[72] == 'S';
}

/* .bpt: a patch count, then the first patch's two degrees: three whole numbers. */
static bool sniff_bpt(const char *buf, size_t len)
{
    size_t at = 0;
    for (int k = 0; k < 3; k++) {
        at = skip_space(buf, len, at);
        size_t start = at;
        while (at < len && isdigit((unsigned char)buf[at]))
            at++;
        if (at == start || at - start > 9 || (at < len && !isspace((unsigned char)buf[at])))
            return false;
    }
    return true;
}

/* VRML: its header, or (the shared .nurbs files) a NurbsSurface node or its first field. */
static bool sniff_vrml(const char *buf, size_t len)
{
    static const char *const FIRST[] = {"#VRML", "NurbsSurface", "uOrder", "vOrder", "uDimension", "vDimension",
                                        "Shape", "Transform", "Group", "DEF"};
    size_t at = skip_space(buf, len, 0);
    for (size_t k = 0; k < sizeof FIRST / sizeof *FIRST; k++) {
        size_t n = strlen(FIRST[k]);
        if (len - at >= n && !memcmp(buf + at, FIRST[k], n) &&
            (len - at == n || !isalnum((unsigned char)buf[at + n]) || k == 0))
            return true;
    }
    return false;
}

/* DICOM: "DICM" after the preamble, or (without one) a first element of group 0002 or 0008 in
 * explicit VR (an implicit VR guess is left to application/dicom: raw samples could begin so). */
bool format_sniff_dicom(const char *buf, size_t len)
{
    if (len >= 132 && !memcmp(buf + 128, "DICM", 4))
        return true;
    return dicom_sniff(buf, len) && buf[4] >= 'A' && buf[4] <= 'Z' && buf[5] >= 'A' && buf[5] <= 'Z';
}

bool format_sniff_nrrd(const char *buf, size_t len) { return len >= 4 && !memcmp(buf, "NRRD", 4); }

bool format_sniff_mha(const char *buf, size_t len)
{
    return len >= 10 && (!memcmp(buf, "ObjectType", 10) || !memcmp(buf, "NDims", 5));
}

static bool sniff_nifti(const char *buf, size_t len) { return nifti_sniff_body(buf, len); }

/* ---- the table ---- */

/* In the order bodies are sniffed on each route. */
const struct input_format INPUT_FORMATS[] = {
    {"json", {NULL}, {".json"}, {"application/json", "application/scene+json"}, IN_SCENES | IN_MODEL, sniff_json,
     "JSON (application/json)"},
    {"frep", {"json"}, {".json"}, {"application/json"}, IN_VOLUMES, format_sniff_json_object,
     "an FRep object's JSON (application/json)"},
    {"iges", {"igs"}, {".igs", ".iges"}, {"model/iges", "application/iges", "application/x-iges"}, IN_SCENES,
     sniff_iges, "IGES trimmed surfaces (model/iges)"},
    {"bpt", {NULL}, {".bpt"}, {"model/x-bpt", "application/x-bpt"}, IN_SCENES, sniff_bpt,
     "Bézier patches, .bpt (model/x-bpt)"},
    {"nurbs", {"vrml", "wrl"}, {".nurbs", ".wrl", ".vrml"}, {"model/vrml", "x-world/x-vrml"}, IN_SCENES, sniff_vrml,
     "VRML NURBS surfaces (model/vrml)"},
    {"dicom", {"dcm"}, {".dcm"}, {"application/dicom"}, IN_VOLUME | IN_MODEL | IN_VOLUMES, format_sniff_dicom,
     "DICOM (application/dicom; a series as multipart/form-data, an image a part)"},
    {"nifti", {"nii"}, {".nii.gz", ".nii"}, {"application/x-nifti", "image/x-nifti"}, IN_VOLUMES, sniff_nifti,
     "NIfTI-1 or -2 (application/x-nifti; .nii.gz also as application/gzip)"},
    {"nrrd", {"nhdr"}, {".nrrd", ".nhdr"}, {"application/x-nrrd", "image/x-nrrd"}, IN_VOLUMES, format_sniff_nrrd,
     "NRRD (application/x-nrrd; a detached .nhdr with its data file as multipart/form-data)"},
    {"mha", {"mhd", "metaimage"}, {".mha", ".mhd"}, {"application/x-metaimage", "application/x-mha", "image/x-mha"},
     IN_VOLUMES, format_sniff_mha,
     "MetaImage (application/x-metaimage; a detached .mhd with its data file as multipart/form-data)"},
    {"raw", {NULL}, {".raw"}, {"application/octet-stream"}, IN_VOLUMES, NULL,
     "raw samples with ?dims and ?type (application/octet-stream)"},
};
const size_t N_INPUT_FORMATS = sizeof INPUT_FORMATS / sizeof *INPUT_FORMATS;

/* Types that name no format: the body is sniffed (or, multipart, its parts are: a series, a
 * detached header and its data file). */
static const struct {
    const char *media;
    unsigned routes;
} SNIFFED[] = {{"text/plain", IN_SCENES | IN_MODEL},
               {"application/octet-stream", IN_SCENES | IN_MODEL},
               {"application/gzip", IN_VOLUMES},
               {"multipart/form-data", IN_VOLUMES},
               {"application/x-www-form-urlencoded", ~0u} /* curl -d's default */};

/* Whether the type (without its parameters) is media. */
static bool same_type(const char *ct, size_t len, const char *media)
{
    return strlen(media) == len && !strncasecmp(ct, media, len);
}

const char *input_format_of_media(const char *ct, unsigned route)
{
    if (!ct || !*ct)
        return "";
    size_t len = strcspn(ct, ";");
    while (len > 0 && isspace((unsigned char)ct[len - 1]))
        len--;
    for (size_t k = 0; k < sizeof SNIFFED / sizeof *SNIFFED; k++)
        if ((SNIFFED[k].routes & route) && same_type(ct, len, SNIFFED[k].media))
            return "";
    for (size_t k = 0; k < N_INPUT_FORMATS; k++)
        for (int m = 0; (INPUT_FORMATS[k].routes & route) && m < FORMAT_MAX_NAMES && INPUT_FORMATS[k].media[m]; m++)
            if (same_type(ct, len, INPUT_FORMATS[k].media[m]))
                return INPUT_FORMATS[k].name;
    return NULL;
}

const struct input_format *input_format_named(const char *name, unsigned route)
{
    for (size_t k = 0; name && k < N_INPUT_FORMATS; k++) {
        const struct input_format *f = &INPUT_FORMATS[k];
        if (!(f->routes & route))
            continue;
        if (!strcasecmp(name, f->name))
            return f;
        for (int a = 0; a < FORMAT_MAX_NAMES && f->aliases[a]; a++)
            if (!strcasecmp(name, f->aliases[a]))
                return f;
    }
    return NULL;
}

const struct input_format *input_format_of_path(const char *path, unsigned route)
{
    size_t n = path ? strlen(path) : 0;
    for (size_t k = 0; k < N_INPUT_FORMATS; k++) {
        const struct input_format *f = &INPUT_FORMATS[k];
        for (int e = 0; (f->routes & route) && e < FORMAT_MAX_NAMES && f->extensions[e]; e++) {
            size_t m = strlen(f->extensions[e]);
            if (n > m && !strcasecmp(path + n - m, f->extensions[e]))
                return f;
        }
    }
    return NULL;
}

const struct input_format *input_format_sniff(const char *buf, size_t len, unsigned route)
{
    for (size_t k = 0; k < N_INPUT_FORMATS; k++)
        if ((INPUT_FORMATS[k].routes & route) && INPUT_FORMATS[k].sniff && INPUT_FORMATS[k].sniff(buf, len))
            return &INPUT_FORMATS[k];
    return NULL;
}

/* Each format of route, by fn, joined as a list in out ("a, b or c"). */
static void said(unsigned route, bool names, char *out, size_t cap)
{
    size_t n = 0, count = 0, done = 0;
    for (size_t k = 0; k < N_INPUT_FORMATS; k++)
        count += (INPUT_FORMATS[k].routes & route) != 0;
    out[0] = 0;
    for (size_t k = 0; k < N_INPUT_FORMATS && n < cap; k++) {
        if (!(INPUT_FORMATS[k].routes & route))
            continue;
        done++;
        const char *sep = done == 1 ? "" : done == count ? (names ? " or " : "; or ") : names ? ", " : "; ";
        n += (size_t)snprintf(out + n, cap - n, "%s%s", sep, names ? INPUT_FORMATS[k].name : INPUT_FORMATS[k].what);
    }
}

void input_formats_said(unsigned route, char *out, size_t cap) { said(route, false, out, cap); }
void input_format_names(unsigned route, char *out, size_t cap) { said(route, true, out, cap); }

/* ---- GET /formats ---- */

static json_t *routes_json(unsigned routes)
{
    static const char *const PATHS[] = {"/render", "/volume", "/model", "/isosurface", "/matrix-model"};
    json_t *a = json_array();
    for (int k = 0; a && k < 5; k++)
        if (routes & (1u << k))
            json_array_append_new(a, json_string(PATHS[k]));
    return a;
}

static json_t *names_json(const char *const *names)
{
    json_t *a = json_array();
    for (int k = 0; a && k < FORMAT_MAX_NAMES && names[k]; k++)
        json_array_append_new(a, json_string(names[k]));
    return a;
}

char *input_formats_json(void)
{
    json_t *list = json_array(), *sniffed = json_object();
    for (size_t k = 0; list && k < N_INPUT_FORMATS; k++) {
        const struct input_format *f = &INPUT_FORMATS[k];
        json_array_append_new(list, json_pack("{s:s, s:o, s:o, s:o, s:o, s:b, s:s}", "name", f->name, "aliases",
                                              names_json(f->aliases), "extensions", names_json(f->extensions), "media",
                                              names_json(f->media), "routes", routes_json(f->routes), "sniffed",
                                              f->sniff != NULL, "description", f->what));
    }
    for (size_t k = 0; sniffed && k < sizeof SNIFFED / sizeof *SNIFFED; k++)
        json_object_set_new(sniffed, SNIFFED[k].media, routes_json(SNIFFED[k].routes));
    json_t *o = json_pack("{s:o, s:o}", "formats", list, "sniffed_media", sniffed);
    char *text = o ? json_dumps(o, JSON_COMPACT) : NULL;
    json_decref(o);
    return text;
}

/* ---- what is not read ---- */

/* Formats people post by mistake, by their magic: said by name, never read. */
static const struct {
    const char *magic;
    size_t n;
    const char *what;
} FOREIGN[] = {{"\x89PNG\r\n\x1a\n", 8, "a PNG image"},
               {"\xff\xd8\xff", 3, "a JPEG image"},
               {"GIF8", 4, "a GIF image"},
               {"II*\0", 4, "a TIFF image"},
               {"MM\0*", 4, "a TIFF image"},
               {"PK\x03\x04", 4, "a ZIP archive"},
               {"%PDF", 4, "a PDF document"},
               {"ISO-10303-21", 12, "a STEP file (Open CASCADE or a CAD system can write it as IGES)"},
               {"solid ", 6, "an STL mesh"},
               {"ply\n", 4, "a PLY mesh"},
               {"BZh", 3, "bzip2 data"},
               {"\xfd" "7zXZ", 5, "xz data"},
               {"\x1f\x8b", 2, "gzip data that is not a NIfTI file"}};

int input_refuse_foreign(const char *buf, size_t len, unsigned route, const char *path, struct sf_err *err)
{
    for (size_t k = 0; k < sizeof FOREIGN / sizeof *FOREIGN; k++)
        if (len >= FOREIGN[k].n && !memcmp(buf, FOREIGN[k].magic, FOREIGN[k].n)) {
            char names[256];
            input_format_names(route, names, sizeof names);
            return sf_fail(err, SF_EFORMAT, "", "the body is %s, which is not read: %s reads %s (GET /formats)",
                           FOREIGN[k].what, path, names);
        }
    return 0;
}
