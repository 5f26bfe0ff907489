/* model_scene.c - a scene as a model (POST /volume, surfd volume): whether a body is a scene, and
 * the volume its patches enclose when they close (edge to edge, or trimmed surfaces along their
 * boundaries), refused with the first open or flipped object's pointer when they do not. */
#include "model_json_internal.h"

#include <jansson.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "../core/base/clock.h"
#include "../core/geom/enclosed.h"
#include "json_in.h"

/* The scene format of a body: as named, but an IGES file is one whatever its Content-Type said
 * (curl sends files as forms, and a JSON default would refuse it). */
enum scene_format scene_body_format(const char *buf, size_t len, const char *format)
{
    enum scene_format f = scene_format_parse(format);
    return (f == SCENE_JSON || f == SCENE_UNKNOWN) && scene_format_sniff(buf, len) == SCENE_IGES ? SCENE_IGES : f;
}

bool model_body_is_scene(const char *buf, size_t len, const char *format)
{
    if (scene_body_format(buf, len, format) == SCENE_IGES)
        return true;
    enum scene_format f = scene_format_parse(format);
    if (f == SCENE_BPT || f == SCENE_VRML || f == SCENE_IGES) /* (by any of its names) */
        return true;
    if (format && *format && strcmp(format, "json"))
        return false;
    return !json_has_member(buf, len, "slices") &&
           (json_has_member(buf, len, "objects") || json_has_member(buf, len, "patches"));
}

/* Trimmed surfaces as a solid: their area over the trimmed domains, and the volume they enclose
 * when their boundaries meet (enclosed_shell), each turned the way its neighbours face. Patches
 * whose edges meet parts of others (a contour model's: its caps' fans against the walls' rows)
 * close the same way (trimmed false: no list of surfaces). */
static int trimmed_figures(const struct scene *sc, const struct patch_set *ps, bool trimmed, double t0, double t1,
                           const struct sf_progress *pr, char **json, struct sf_err *err)
{
    struct enclosed e;
    double *vol = malloc(sizeof *vol * (size_t)sc->n_objects), *area = malloc(sizeof *area * (size_t)sc->n_objects);
    struct shell_part *parts = malloc(sizeof *parts * (size_t)sc->n_objects);
    signed char *sign = malloc((size_t)sc->n_objects);
    struct shell sh;
    int rc = 0;
    if (!vol || !area || !parts || !sign || enclosed_measure_objects(ps, &e, vol, area, sc->n_objects))
        rc = sf_fail(err, SF_ENOMEM, "", "out of memory");
    double diag = hypot(hypot(e.hi[0] - e.lo[0], e.hi[1] - e.lo[1]), e.hi[2] - e.lo[2]);
    for (int k = 0; !rc && k < sc->n_objects; k++)
        parts[k] = (struct shell_part){&sc->objects[k].surf, sc->objects[k].trim};
    if (!rc && (rc = enclosed_shell(parts, sc->n_objects, SHELL_GAP_REL * diag, pr, &sh, sign)))
        rc = rc == SF_ECANCEL ? sf_fail(err, rc, "", "cancelled")
             : rc == SF_ELIMIT
                 ? sf_fail(err, rc, "", "the surfaces' boundaries crowd together: matching their points would take "
                           "some %.3g tests, over the limit of %.3g", sh.tests, SHELL_MAX_TESTS)
                 : sf_fail(err, SF_ENOMEM, "", "out of memory");
    char where[32];
    if (!rc && sh.open_samples) {
        scene_object_pointer(sc, sh.open_object, where, sizeof where);
        const char *name = sc->objects[sh.open_object].name;
        rc = sf_fail(err, SF_EINVAL, where, "the surfaces do not bound a closed solid: %zu of %zu boundary points meet no "
                     "other surface within %.3g mm, the first of this surface%s%s%s at (%.4g, %.4g, %.4g) mm; their "
                     "area is %.6g mm²", sh.open_samples, sh.samples, SHELL_GAP_REL * diag, *name ? " (" : "", name,
                     *name ? ")" : "", sh.open_at[0], sh.open_at[1], sh.open_at[2], e.area);
    } else if (!rc && sh.conflicts) {
        rc = sf_fail(err, SF_EINVAL, "", "the surfaces close, but no choice of their sides faces them all the same way "
                     "(%d neighbouring pairs disagree): a one-sided shell", sh.conflicts);
    }
    double v = 0;
    int turned = 0;
    for (int k = 0; !rc && k < sc->n_objects; k++)
        v += sign[k] * vol[k];
    for (int k = 0; !rc && k < sc->n_objects; k++)
        turned += (v < 0 ? -sign[k] : sign[k]) < 0;
    double t2 = sf_now_ms();
    json_t *list = rc ? NULL : json_array();
    for (int k = 0; list && trimmed && k < sc->n_objects; k++) {
        scene_object_pointer(sc, k, where, sizeof where);
        json_array_append_new(list, json_pack("{s:s, s:s, s:f, s:b}", "entity", where, "name", sc->objects[k].name,
                                              "area_mm2", area[k], "turned", (v < 0 ? -sign[k] : sign[k]) < 0));
    }
    if (!rc)
        *json = dump(json_pack("{s:s, s:i, s:o, s:I, s:b, s:s, s:i, s:f, s:f, s:{s:f}, s:I, s:[[f,f,f],[f,f,f]], s:{s:f, "
                               "s:f}}", "kind", trimmed ? "trimmed surfaces" : "patches", "surfaces", sc->n_objects, "surface_figures", list,
                               "patches", (json_int_t)ps->n,
                               "closed", 1, "orientation", turned ? "mixed" : v >= 0 ? "outward" : "inward",
                               "surfaces_turned", turned, "volume_mm3", fabs(v), "area_mm2", e.area, "volume", "exact",
                               fabs(v), "boundary_points", (json_int_t)sh.samples, "bounds", e.lo[0], e.lo[1], e.lo[2],
                               e.hi[0], e.hi[1], e.hi[2], "timings_ms", "read", t1 - t0, "volume", t2 - t1),
                     err);
    free(vol);
    free(area);
    free(parts);
    free(sign);
    return rc ? rc : (*json ? 0 : err->code);
}

/* A scene's patches as a solid (POST /volume): the volume they enclose, when they close. */
int scene_figures(const char *buf, size_t len, const char *format, const struct sf_progress *pr, char **json,
                  struct sf_err *err)
{
    double t0 = sf_now_ms();
    struct scene sc;
    enum image_format img;
    /* an IGES part's loops, and the matching of their points, stop at a cancel */
    struct sf_span reading = {pr, 0, 0.5}, closing = {pr, 0.5, 1};
    const struct sf_progress read_pr = {sf_span_poll, &reading}, close_pr = {sf_span_poll, &closing};
    const struct model_resolver polled = {.progress = pr ? &read_pr : NULL};
    int rc = scene_parse_models(buf, len, scene_body_format(buf, len, format), &polled, &sc, &img, err);
    if (rc)
        return rc;
    struct patch_set ps;
    struct enclosed e;
    double t1 = sf_now_ms();
    if ((rc = scene_patches(&sc, &ps, err))) {
        scene_free(&sc);
        return rc;
    }
    bool trimmed = false;
    for (int k = 0; k < sc.n_objects; k++)
        trimmed |= sc.objects[k].trim != NULL;
    if (!trimmed && enclosed_measure(&ps, &e))
        rc = sf_fail(err, SF_ENOMEM, "", "out of memory");
    else if (trimmed || e.open_edges) { /* trimmed, or edges meeting parts of others: closed along the boundaries */
        rc = trimmed_figures(&sc, &ps, trimmed, t0, t1, pr ? &close_pr : NULL, json, err);
        nurbs_patch_set_free(&ps);
        scene_free(&sc);
        return rc;
    } else if (e.flipped_edges) {
        char where[32];
        snprintf(where, sizeof where, "/objects/%d", e.open_object);
        rc = sf_fail(err, SF_EINVAL, where, "neighbouring patches face opposite ways across %zu edges (this object has one)",
                     e.flipped_edges / 2);
    }
    double t2 = sf_now_ms(), v = fabs(e.volume);
    if (!rc)
        *json = dump(json_pack("{s:s, s:I, s:b, s:s, s:f, s:f, s:{s:f}, s:[[f,f,f],[f,f,f]], s:{s:f, s:f}}", "kind",
                               "patches", "patches", (json_int_t)ps.n, "closed", 1, "orientation",
                               e.volume >= 0 ? "outward" : "inward", "volume_mm3", v, "area_mm2", e.area, "volume",
                               "exact", v, "bounds", e.lo[0], e.lo[1], e.lo[2], e.hi[0], e.hi[1], e.hi[2],
                               "timings_ms", "read", t1 - t0, "volume", t2 - t1),
                     err);
    nurbs_patch_set_free(&ps);
    scene_free(&sc);
    return rc ? rc : (*json ? 0 : err->code);
}

