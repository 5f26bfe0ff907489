/* cmd_model.c - `surfd volume FILE` and `surfd model FILE`: contours in, the model's figures
 * out as JSON (the fields of API.md's model resource that exist so far), offline. */
#include <jansson.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "../api/contour_json.h"
#include "../core/model.h"
#include "cli.h"

static double now_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec * 1e3 + ts.tv_nsec / 1e6;
}

int cmd_volume(int argc, char **argv)
{
    if (argc != 2) {
        fprintf(stderr, "usage: surfd volume CONTOURS.json   (also: surfd model CONTOURS.json)\n");
        return 2;
    }
    FILE *f = fopen(argv[1], "rb");
    if (!f) {
        perror(argv[1]);
        return 1;
    }
    fseek(f, 0, SEEK_END);
    long len = ftell(f);
    fseek(f, 0, SEEK_SET);
    char *buf = len >= 0 && len < (1L << 30) ? malloc((size_t)len + 1) : NULL;
    size_t got = buf ? fread(buf, 1, (size_t)len, f) : 0;
    fclose(f);
    if (!buf || got != (size_t)len) {
        free(buf);
        fprintf(stderr, "surfd: %s: cannot read\n", argv[1]);
        return 1;
    }
    struct contour_set cs;
    struct contour_request req;
    struct sf_err err = {0};
    double t0 = now_ms();
    int rc = contour_parse_json(buf, (size_t)len, &cs, &req, &err);
    free(buf);
    if (rc) {
        fprintf(stderr, "surfd: %s: %s%s%s\n", argv[1], err.message, err.pointer[0] ? " at " : "", err.pointer);
        return 1;
    }
    struct patch_set ps = {0};
    if (model_parabolic(&cs, &ps, &err)) {
        fprintf(stderr, "surfd: %s\n", err.message);
        contour_set_free(&cs);
        return 1;
    }
    nurbs_patches_fix(&ps);
    double t1 = now_ms();
    struct model_measures m;
    model_measure(&ps, &m);
    struct contour_baselines b;
    contour_baselines(&cs, &b);
    double t2 = now_ms();
    json_t *o = json_pack("{s:s, s:s, s:s, s:i, s:I, s:f, s:f, s:{s:f, s:f, s:f, s:f}, s:[[f,f,f],[f,f,f]], s:{s:f, s:f}}",
                          "name", req.name, "method", req.method, "caps", req.caps, "slices", cs.n_slices, "patches",
                          (json_int_t)ps.n, "volume_mm3", m.volume, "area_mm2", m.area, "volume", "exact", m.volume,
                          "trapezoid", b.trapezoid, "cavalieri", b.cavalieri, "frustum", b.frustum, "bounds", m.lo[0],
                          m.lo[1], m.lo[2], m.hi[0], m.hi[1], m.hi[2], "timings_ms", "fit", t1 - t0, "volume", t2 - t1);
    char *s = json_dumps(o, JSON_COMPACT | JSON_REAL_PRECISION(12));
    printf("%s\n", s);
    free(s);
    json_decref(o);
    nurbs_patch_set_free(&ps);
    contour_set_free(&cs);
    return 0;
}
