/* iges.h - the IGES reader (iges.c) with a poll: scene_parse_iges (scene_io.h) is it without one.
 * A part's trim loops are counted from what it declares before any is made, and a part whose
 * loops would come to more than the reader's budget of trim points is refused (SF_ELIMIT, 422)
 * at the surface where the count passes it, so a few kilobytes cannot cost gigabytes. */
#ifndef SURFD_IGES_H
#define SURFD_IGES_H

#include <stddef.h>

#include "../core/base/err.h"
#include "../core/trace/scene.h"

/* scene_parse_iges, polling pr (NULL: never stops) between surfaces and while their loops are
 * made, with the share of the counted trim points made so far: SF_ECANCEL when it says stop. On
 * success the caller owns the scene (scene_free()); on failure nothing is left to free. */
int iges_parse(const char *buf, size_t len, const struct sf_progress *pr, struct scene *sc, struct sf_err *err);

#endif
