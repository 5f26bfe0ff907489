/* test_enclosed.c - the volume any closed patch set encloses, through the figures path POST /volume
 * takes for a scene: a unit cube of six bilinear patches, a NURBS sphere (rational, poles collapsed),
 * the teapot (open: refused with the object's pointer), a cube with a face missing or turned. */
#include "../../api/model_json.h"
#include "../unit.h"

#include <stdlib.h>

static const double FACES[6][3][3] = { /* origin, a, b with a × b outward */
    {{0, 0, 0}, {0, 1, 0}, {1, 0, 0}}, {{0, 0, 1}, {1, 0, 0}, {0, 1, 0}}, {{0, 0, 0}, {1, 0, 0}, {0, 0, 1}},
    {{0, 1, 0}, {0, 0, 1}, {1, 0, 0}}, {{0, 0, 0}, {0, 0, 1}, {0, 1, 0}}, {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}};

/* The unit cube's faces as bilinear patches; skip: a face left out (-1: none); turn: a face whose
 * u runs the other way (-1: none). */
static int cube(char *out, size_t cap, int skip, int turn)
{
    int n = snprintf(out, cap, "{\"objects\":[");
    for (int f = 0, first = 1; f < 6; f++) {
        if (f == skip)
            continue;
        n += snprintf(out + n, cap - (size_t)n, "%s{\"degree\":[1,1],\"points\":[", first ? "" : ",");
        first = 0;
        for (int i = 0; i < 2; i++)
            for (int j = 0; j < 2; j++) {
                int ii = f == turn ? 1 - i : i;
                const double *o = FACES[f][0], *a = FACES[f][1], *b = FACES[f][2];
                n += snprintf(out + n, cap - (size_t)n, "%s[%g,%g,%g]", i || j ? "," : "", o[0] + ii * a[0] + j * b[0],
                              o[1] + ii * a[1] + j * b[1], o[2] + ii * a[2] + j * b[2]);
            }
        n += snprintf(out + n, cap - (size_t)n, "]}");
    }
    return n + snprintf(out + n, cap - (size_t)n, "]}");
}

static double volume_of(const char *json)
{
    const char *v = json ? strstr(json, "\"volume_mm3\":") : NULL;
    return v ? atof(v + 13) : NAN;
}

TEST(unit_cube_and_its_faults)
{
    char text[4096], *json = NULL;
    struct sf_err err = {0};
    int n = cube(text, sizeof text, -1, -1);
    CHECK(model_figures(text, (size_t)n, "json", "", NULL, &json, &err) == 0);
    CHECK_NEAR(volume_of(json), 1.0, 1e-14);
    CHECK(json && strstr(json, "\"closed\":true") && strstr(json, "\"orientation\":\"outward\""));
    free(json);
    json = NULL;
    n = cube(text, sizeof text, 3, -1); /* the face y = 1 left out */
    CHECK(model_figures(text, (size_t)n, "json", "", NULL, &json, &err) == SF_EINVAL);
    CHECK(strstr(err.message, "closed solid") && !strncmp(err.pointer, "/objects/", 9));
    n = cube(text, sizeof text, -1, 4); /* the face x = 0 turned inward */
    err = (struct sf_err){0}; /* the first error is kept: a fresh one for the next */
    CHECK(model_figures(text, (size_t)n, "json", "", NULL, &json, &err) == SF_EINVAL);
    CHECK(strstr(err.message, "opposite ways") && !strcmp(err.pointer, "/objects/4"));
}

/* A sphere of radius 3 as one NURBS surface: quadratic, rational, a full circle round z times a
 * half circle from pole to pole (whose rows collapse to points there). */
TEST(nurbs_sphere)
{
    const double r = 3, h = sqrt(0.5);
    const double cx[9] = {1, 1, 0, -1, -1, -1, 0, 1, 1}, cy[9] = {0, 1, 1, 1, 0, -1, -1, -1, 0};
    const double wu[9] = {1, h, 1, h, 1, h, 1, h, 1};
    const double rho[5] = {0, r, r, r, 0}, z[5] = {-r, -r, 0, r, r}, wv[5] = {1, h, 1, h, 1};
    char text[8192];
    int n = snprintf(text, sizeof text, "{\"objects\":[{\"type\":\"nurbs\",\"degree\":[2,2],\"size\":[9,5],"
                                        "\"knots_u\":[0,0,0,0.25,0.25,0.5,0.5,0.75,0.75,1,1,1],"
                                        "\"knots_v\":[0,0,0,0.5,0.5,1,1,1],\"points\":[");
    for (int i = 0; i < 9; i++)
        for (int j = 0; j < 5; j++)
            n += snprintf(text + n, sizeof text - (size_t)n, "%s[%.17g,%.17g,%.17g]", i || j ? "," : "",
                          rho[j] * cx[i], rho[j] * cy[i], z[j]);
    n += snprintf(text + n, sizeof text - (size_t)n, "],\"weights\":[");
    for (int i = 0; i < 9; i++)
        for (int j = 0; j < 5; j++)
            n += snprintf(text + n, sizeof text - (size_t)n, "%s%.17g", i || j ? "," : "", wu[i] * wv[j]);
    n += snprintf(text + n, sizeof text - (size_t)n, "]}]}");
    char *json = NULL;
    struct sf_err err = {0};
    CHECK(model_figures(text, (size_t)n, "json", "", NULL, &json, &err) == 0);
    if (!json)
        fprintf(stderr, "  %s at %s\n", err.message, err.pointer);
    double v = volume_of(json), exact = 4.0 / 3.0 * M_PI * r * r * r;
    fprintf(stderr, "  sphere: %.12f, exact %.12f (%.1e)\n", v, exact, (v - exact) / exact);
    CHECK(fabs(v - exact) < 1e-9 * exact);
    const char *a = json ? strstr(json, "\"area_mm2\":") : NULL;
    CHECK(a && fabs(atof(a + 11) - 4 * M_PI * r * r) < 1e-9 * 4 * M_PI * r * r);
    free(json);
}

/* Newell's teapot has no bottom: open, refused with the pointer of an object that has an open edge. */
TEST(teapot_is_open)
{
    size_t len;
    char *buf = unit_data("scenes", "teapot.bpt", &len), *json = NULL;
    struct sf_err err = {0};
    CHECK(buf && model_figures(buf, len, "bpt", "", NULL, &json, &err) == SF_EINVAL);
    CHECK(strstr(err.message, "closed solid") && !strncmp(err.pointer, "/objects/", 9));
    free(buf);
}

int main(void)
{
    RUN(unit_cube_and_its_faults);
    RUN(nurbs_sphere);
    RUN(teapot_is_open);
    UNIT_END();
}
