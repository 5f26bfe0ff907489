/* scene_io.c - which parser reads a scene: its format by the names and magic of the formats' table
 * (formats.h), and the dispatch to the JSON, .bpt, VRML and IGES parsers (scene_io.h). It parses
 * nothing itself. */
#include "scene_io.h"

#include <string.h>

#include "formats.h"
#include "iges.h"

/* A scene format's enum by the table's name (formats.c: every route that reads a scene, /render,
 * /volume, /model and the CLI, names them there). */
static enum scene_format scene_format_of(const struct input_format *f)
{
    static const struct {
        const char *name;
        enum scene_format format;
    } BY_NAME[] = {{"json", SCENE_JSON}, {"bpt", SCENE_BPT}, {"nurbs", SCENE_VRML}, {"iges", SCENE_IGES}};
    for (size_t k = 0; f && k < sizeof BY_NAME / sizeof *BY_NAME; k++)
        if (!strcmp(f->name, BY_NAME[k].name))
            return BY_NAME[k].format;
    return (enum scene_format)-1;
}

enum scene_format scene_format_parse(const char *name)
{
    if (!name || !*name)
        return SCENE_UNKNOWN;
    return scene_format_of(input_format_named(name, IN_RENDER));
}

enum scene_format scene_format_sniff(const char *buf, size_t len)
{
    const struct input_format *f = input_format_sniff(buf, len, IN_RENDER);
    return f ? scene_format_of(f) : SCENE_VRML; /* (the VRML reader says what it cannot read) */
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
    int rc = fmt == SCENE_UNKNOWN ? input_refuse_foreign(buf, len, IN_RENDER, "a route of scenes", err) : 0;
    if (rc)
        return rc;
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
