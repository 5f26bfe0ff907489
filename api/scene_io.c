/* scene_io.c - which parser reads a scene: the table of the names its format goes by, the sniffing
 * of a body that names none, and the dispatch to the JSON, .bpt, VRML and IGES parsers (scene_io.h).
 * It parses nothing itself. */
#include "scene_io.h"

#include <ctype.h>
#include <string.h>

#include "iges.h"

/* The names a scene's format goes by, in ?format= and as a file's extension: every route that reads
 * a scene (/render, /volume, /model, the CLI) takes them from here. */
static const struct {
    const char *name;
    enum scene_format format;
} SCENE_FORMATS[] = {{"json", SCENE_JSON}, {"bpt", SCENE_BPT},   {"nurbs", SCENE_VRML}, {"vrml", SCENE_VRML},
                     {"wrl", SCENE_VRML},  {"iges", SCENE_IGES}, {"igs", SCENE_IGES}};

enum scene_format scene_format_parse(const char *name)
{
    if (!name || !*name)
        return SCENE_UNKNOWN;
    for (size_t k = 0; k < sizeof SCENE_FORMATS / sizeof *SCENE_FORMATS; k++)
        if (!strcmp(name, SCENE_FORMATS[k].name))
            return SCENE_FORMATS[k].format;
    return (enum scene_format)-1;
}

enum scene_format scene_format_sniff(const char *buf, size_t len)
{
    size_t k = 0;
    while (k < len && isspace((unsigned char)buf[k]))
        k++;
    if (k < len && (buf[k] == '{' || buf[k] == '['))
        return SCENE_JSON;
    const char *nl = memchr(buf, '\n', len);
    size_t first = nl ? (size_t)(nl - buf) : len;
    if (first >= 73 && buf[72] == 'S') /* an IGES Start line: the section letter in column 73 */
        return SCENE_IGES;
    if (k < len && isdigit((unsigned char)buf[k]))
        return SCENE_BPT;
    return SCENE_VRML;
}

int scene_parse(const char *buf, size_t len, enum scene_format fmt, struct scene *sc, enum image_format *img,
                struct sf_err *err)
{
    return scene_parse_models(buf, len, fmt, NULL, sc, img, err);
}

int scene_parse_models(const char *buf, size_t len, enum scene_format fmt, const struct model_resolver *models,
                       struct scene *sc, enum image_format *img, struct sf_err *err)
{
    *img = IMG_PNG;
    if (len > SCENE_MAX_BODY)
        return sf_fail(err, SF_ELIMIT, "", "scene of %zu bytes is over the limit of %u", len, SCENE_MAX_BODY);
    if (fmt == SCENE_UNKNOWN)
        fmt = scene_format_sniff(buf, len);
    switch (fmt) {
    case SCENE_JSON: return scene_parse_json(buf, len, models, sc, img, err);
    case SCENE_BPT: return scene_parse_bpt(buf, len, sc, err);
    case SCENE_VRML: return scene_parse_vrml(buf, len, sc, err);
    case SCENE_IGES: return iges_parse(buf, len, models ? models->progress : NULL, sc, err);
    default: return sf_fail(err, SF_EFORMAT, "", "unknown scene format");
    }
}
