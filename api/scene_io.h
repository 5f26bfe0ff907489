/* scene_io.h - request bodies to struct scene: the JSON scene of API.md (with JSON pointers in
 * every error; scene_json.c), Newell's .bpt patch files and VRML97 NurbsSurface fragments, as users
 * have them (scene_text.c), and IGES trimmed NURBS (iges.c), each by the format table and sniffing
 * of scene_io.c. Unparsable input fails with SF_EFORMAT (HTTP 400), parsable but invalid with
 * SF_EINVAL or SF_ELIMIT (422). On success the caller owns the scene (scene_free()); on failure
 * nothing is left to free. */
#ifndef SURFD_SCENE_IO_H
#define SURFD_SCENE_IO_H

#include <stddef.h>

#include "../core/base/err.h"
#include "../core/trace/scene.h"

#define SCENE_MAX_BODY (256u << 20) /* bytes of scene text read at most */

enum image_format { IMG_PNG, IMG_EXR, IMG_TIFF };

enum scene_format { SCENE_JSON, SCENE_BPT, SCENE_VRML, SCENE_IGES, SCENE_UNKNOWN };

/* "json", "bpt", "nurbs"/"vrml", "iges"/"igs" -> enum; NULL or "" -> SCENE_UNKNOWN (sniff the body). */
enum scene_format scene_format_parse(const char *name);
/* Guesses the format from the first bytes. */
enum scene_format scene_format_sniff(const char *buf, size_t len);

/* What a scene is parsed within. Where the objects {"type": "model", "id": ...} of a JSON scene
 * come from: objects() appends stored model id's objects and meshes to sc, of material mat, and
 * returns 0, or fails with err's pointer at <where>/id (no such model: SF_EINVAL; the store failed:
 * SF_EIO; the meshes of all of a scene's model objects over the resolver's limit: SF_ELIMIT, each
 * reference a copy: a 3 KB scene naming one model 50 times cost 5.5 GB), or as the model's objects
 * fail (at <where>). Without one, model objects are refused. progress: polled by the parses that
 * can take long (an IGES part's trimming loops, iges.h); NULL, never stops. */
struct model_resolver {
    int (*objects)(void *ctx, const char *id, const struct material *mat, const char *where, struct scene *sc,
                   struct sf_err *err);
    void *ctx;
    const struct sf_progress *progress;
};

/* Parses buf as fmt (SCENE_UNKNOWN: sniffed). *img receives image.format (PNG by default). */
int scene_parse(const char *buf, size_t len, enum scene_format fmt, struct scene *sc, enum image_format *img,
                struct sf_err *err);
/* The same, with stored models (models may be NULL). */
int scene_parse_models(const char *buf, size_t len, enum scene_format fmt, const struct model_resolver *models,
                       struct scene *sc, enum image_format *img, struct sf_err *err);

int scene_parse_json(const char *buf, size_t len, const struct model_resolver *models, struct scene *sc,
                     enum image_format *img, struct sf_err *err);
int scene_parse_bpt(const char *buf, size_t len, struct scene *sc, struct sf_err *err);
int scene_parse_vrml(const char *buf, size_t len, struct scene *sc, struct sf_err *err);
/* IGES 5.3 trimmed NURBS (iges.c): independent 128, 143 and 144 entities, in millimetres; errors
 * name the entity by its first directory line ("D5"). */
int scene_parse_iges(const char *buf, size_t len, struct scene *sc, struct sf_err *err);

int image_format_parse(const char *name, enum image_format *f);
const char *image_format_mime(enum image_format f);

#endif
