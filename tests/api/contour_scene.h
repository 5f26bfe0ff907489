/* contour_scene.h - the trace tests' contour model: a shared contour file's model as a scene
 * object list, as POST /model then a render make it (its parsed contours and written model kept
 * beside the scene until contour_scene_free). Header-only, for test_bvh.c and test_render.c. */
#ifndef SURFD_TEST_CONTOUR_SCENE_H
#define SURFD_TEST_CONTOUR_SCENE_H

#include "../../api/contour_json.h"
#include "../../api/model_json.h"
#include "../../api/scene_io.h"
#include "../unit.h"

struct contour_scene {
    char *buf, *src;
    struct contour_set cs;
    struct scene sc;
};

/* False when the file is missing or does not make a model (what is made is freed all the same). */
static bool contour_scene_load(const char *file, struct contour_scene *c)
{
    size_t len;
    struct contour_request req;
    struct material mat = scene_default_material();
    memset(c, 0, sizeof *c);
    scene_init(&c->sc);
    if (!(c->buf = unit_data("contours", file, &len)) || contour_parse_json(c->buf, len, &c->cs, &req, NULL))
        return false;
    return (c->src = contour_json_write(&c->cs, &req)) &&
           model_scene_objects(c->src, strlen(c->src), &c->sc, &mat, "/objects/0", NULL) == 0;
}

/* Frees what contour_scene_load made (a zeroed one: nothing). */
static void contour_scene_free(struct contour_scene *c)
{
    scene_free(&c->sc);
    free(c->src);
    if (c->buf)
        contour_set_free(&c->cs);
    free(c->buf);
}

#endif
