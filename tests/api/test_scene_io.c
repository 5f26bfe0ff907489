/* test_scene_io.c - the scene readers: shared files as they are, and every kind of bad input with
 * the right class (SF_EFORMAT -> 400, SF_EINVAL/SF_ELIMIT -> 422) and pointer. */
#include "../../api/scene_io.h"
#include "../unit.h"

#include <stdlib.h>

static int parse(const char *text, enum scene_format fmt, struct sf_err *err, struct scene *out)
{
    struct scene sc;
    enum image_format img;
    memset(err, 0, sizeof *err);
    int rc = scene_parse(text, strlen(text), fmt, &sc, &img, err);
    if (!rc && out)
        *out = sc;
    else if (!rc)
        scene_free(&sc);
    return rc;
}

TEST(shared_scenes_parse)
{
    struct {
        const char *name;
        int objects;
        enum surf_kind kind;
    } files[] = {{"teapot.json", 32, SURF_BEZIER}, {"teapot.bpt", 32, SURF_BEZIER},   {"teacup.json", 26, SURF_BEZIER},
                 {"teacup.bpt", 26, SURF_BEZIER},  {"teaspoon.json", 16, SURF_BEZIER}, {"teaspoon.bpt", 16, SURF_BEZIER},
                 {"duck1.nurbs", 1, SURF_NURBS},   {"duck2.nurbs", 1, SURF_BSPLINE},   {"duck3.nurbs", 1, SURF_BSPLINE}};
    for (size_t k = 0; k < sizeof files / sizeof *files; k++) {
        size_t len;
        char *buf = unit_data("scenes", files[k].name, &len);
        CHECK(buf != NULL);
        if (!buf)
            continue;
        struct scene sc;
        enum image_format img;
        struct sf_err err = {0};
        int rc = scene_parse(buf, len, SCENE_UNKNOWN, &sc, &img, &err);
        if (rc)
            fprintf(stderr, "  %s: %s at %s\n", files[k].name, err.message, err.pointer);
        CHECK(rc == 0);
        if (!rc) {
            CHECK(sc.n_objects == files[k].objects);
            CHECK(sc.objects[0].surf.kind == files[k].kind);
            for (int o = 0; o < sc.n_objects; o++)
                CHECK(nurbs_validate(&sc.objects[o].surf, "", NULL) == 0);
            scene_free(&sc);
        }
        free(buf);
    }
}

/* The .bpt and .json teapots are the same patches in the same order. */
TEST(bpt_equals_json)
{
    size_t la, lb;
    char *a = unit_data("scenes", "teapot.json", &la), *b = unit_data("scenes", "teapot.bpt", &lb);
    struct scene sa, sb;
    enum image_format img;
    REQUIRE(a && b && scene_parse(a, la, SCENE_JSON, &sa, &img, NULL) == 0 && scene_parse(b, lb, SCENE_BPT, &sb, &img, NULL) == 0);
    for (int o = 0; o < 32; o++)
        for (int k = 0; k < 48; k++)
            CHECK_NEAR(sa.objects[o].surf.points[k], sb.objects[o].surf.points[k], 0);
    scene_free(&sa);
    scene_free(&sb);
    free(a);
    free(b);
}

/* VRML orders control points u-fastest: duck1's first 13 (one u row at v = 0) are its pole. */
TEST(vrml_order_and_concatenation)
{
    size_t l1, l2, l3;
    char *d1 = unit_data("scenes", "duck1.nurbs", &l1), *d2 = unit_data("scenes", "duck2.nurbs", &l2), *d3 = unit_data("scenes", "duck3.nurbs", &l3);
    REQUIRE(d1 && d2 && d3);
    struct scene sc;
    enum image_format img;
    REQUIRE(scene_parse(d1, l1, SCENE_VRML, &sc, &img, NULL) == 0);
    const struct surface *s = &sc.objects[0].surf;
    CHECK(s->n_u == 13 && s->n_v == 14);
    for (int i = 1; i < 13; i++) /* point (i, 0) for every i: the collapsed row */
        CHECK_NEAR(s->points[3 * (i * 14)], s->points[0], 0);
    scene_free(&sc);
    char *all = malloc(l1 + l2 + l3 + 3);
    memcpy(all, d1, l1);
    all[l1] = '\n';
    memcpy(all + l1 + 1, d2, l2);
    all[l1 + 1 + l2] = '\n';
    memcpy(all + l1 + l2 + 2, d3, l3);
    CHECK(scene_parse(all, l1 + l2 + l3 + 2, SCENE_UNKNOWN, &sc, &img, NULL) == 0);
    CHECK(sc.n_objects == 3);
    scene_free(&sc);
    free(all);
    free(d1);
    free(d2);
    free(d3);
}

TEST(json_options)
{
    struct scene sc;
    struct sf_err err;
    const char *j = "{\"image\":{\"width\":64,\"height\":32,\"format\":\"exr\",\"aovs\":[\"normal\",\"id\"],\"background\":[0,0,0]},"
                    "\"camera\":{\"eye\":[6,-8,5],\"target\":[0,0,1.5],\"up\":[0,0,1],\"fov_deg\":35},"
                    "\"lights\":[{\"type\":\"point\",\"position\":[1,2,3]},{\"type\":\"directional\",\"direction\":[-1,-1,-2]}],"
                    "\"render\":{\"method\":\"bvh\",\"tolerance\":1e-9,\"shadows\":false},"
                    "\"objects\":[{\"type\":\"bezier\",\"degree\":[1,1],\"points\":[[0,0,0],[1,0,0],[0,1,0],[1,1,1]],"
                    "\"material\":{\"color\":[1,0,0],\"specular\":0.5,\"shininess\":10}}]}";
    CHECK(parse(j, SCENE_JSON, &err, &sc) == 0);
    CHECK(sc.width == 64 && sc.height == 32 && sc.has_camera && sc.n_lights == 2 && sc.lights[0].point);
    CHECK(sc.method == METHOD_BVH && !sc.shadows && sc.aovs == (AOV_NORMAL | AOV_ID));
    CHECK_NEAR(sc.objects[0].mat.color.x, 1, 0);
    CHECK_NEAR(sc.tolerance, 1e-9, 0);
    scene_free(&sc);
}

/* Every rejection: code class and pointer. */
TEST(bad_json_scenes)
{
    const char *obj = "\"degree\":[1,1],\"points\":[[0,0,0],[1,0,0],[0,1,0],[1,1,1]]";
    char buf[1024];
    struct {
        const char *body;
        int code;
        const char *pointer;
    } cases[] = {
        {"{\"objects\": [", SF_EFORMAT, NULL},
        {"", SF_EFORMAT, NULL},
        {"[1,2]", SF_EINVAL, ""},
        {"{}", SF_EINVAL, "/objects"},
        {"{\"objects\":[]}", SF_EINVAL, "/objects"},
        {"{\"objects\":[7]}", SF_EINVAL, "/objects/0"},
        {"{\"objects\":[{\"type\":\"sphere\"}]}", SF_EINVAL, "/objects/0/type"},
        {"{\"objects\":[{\"type\":\"model\",\"id\":\"x\"}]}", SF_EINVAL, "/objects/0/id"}, /* models need the service's store */
        {"{\"objects\":[{\"degree\":[0,1],\"points\":[]}]}", SF_EINVAL, "/objects/0/degree/0"},
        {"{\"objects\":[{\"degree\":[1,1],\"points\":[[0,0,0]]}]}", SF_EINVAL, "/objects/0/points"},
        {"{\"objects\":[{\"degree\":[1,1],\"points\":[[0,0,0],[1,0,0],[0,1],[1,1,1]]}]}", SF_EINVAL, "/objects/0/points/2"},
        {"{\"objects\":[{\"degree\":[1,1],\"points\":[[0,0,0],[1,0,0],[0,1,0],[1,1,\"a\"]]}]}", SF_EINVAL, "/objects/0/points/3/2"},
        {"{\"objects\":[{\"type\":\"bspline\",\"degree\":[1,1],\"size\":[2,2],\"knots_u\":[0,0,1],\"knots_v\":[0,0,1,1],"
         "\"points\":[[0,0,0],[1,0,0],[0,1,0],[1,1,1]]}]}", SF_EINVAL, "/objects/0/knots_u"},
        {"{\"objects\":[{\"type\":\"bspline\",\"degree\":[1,1],\"size\":[1,2]}]}", SF_EINVAL, "/objects/0/size/0"},
        {"{\"objects\":[{\"type\":\"nurbs\",\"degree\":[1,1],\"size\":[2,2],\"knots_u\":[0,0,1,1],\"knots_v\":[0,0,1,1],"
         "\"points\":[[0,0,0],[1,0,0],[0,1,0],[1,1,1]],\"weights\":[1,1,1]}]}", SF_EINVAL, "/objects/0/weights"},
        {"{\"objects\":[{\"type\":\"bspline\",\"degree\":[1,1],\"size\":[1000,2000]}]}", SF_ELIMIT, "/objects/0/size"},
        {"{\"image\":{\"width\":-4},\"objects\":[{%s}]}", SF_EINVAL, "/image/width"},
        {"{\"image\":{\"format\":\"gif\"},\"objects\":[{%s}]}", SF_EINVAL, "/image/format"},
        {"{\"image\":{\"aovs\":[\"depth\"]},\"objects\":[{%s}]}", SF_EINVAL, "/image/aovs/0"},
        {"{\"camera\":{\"eye\":[1,2,3]},\"objects\":[{%s}]}", SF_EINVAL, "/camera/target"},
        {"{\"render\":{\"method\":\"fast\"},\"objects\":[{%s}]}", SF_EINVAL, "/render/method"},
        {"{\"render\":{\"shadows\":1},\"objects\":[{%s}]}", SF_EINVAL, "/render/shadows"},
        {"{\"lights\":[{\"type\":\"spot\"}],\"objects\":[{%s}]}", SF_EINVAL, "/lights/0/type"},
        {"{\"lights\":[{\"direction\":[0,0]}],\"objects\":[{%s}]}", SF_EINVAL, "/lights/0/direction"},
        {"{\"objects\":[{%s,\"material\":{\"shininess\":-1}}]}", SF_EINVAL, "/objects/0/material/shininess"},
        {"{\"objects\":[{%s}],\"objects\":[]}", SF_EFORMAT, NULL},
        /* the objects are read one at a time (json_read_split): what the whole document's parse
         * refuses is refused still, where it is */
        {"{\"objects\":[{%s},]}", SF_EFORMAT, NULL},
        {"{\"objects\":[,{%s}]}", SF_EFORMAT, "line 1, column 13"},
        {"{\"objects\":[{%s},\n{\"type\":\"bezier\" 3}]}", SF_EFORMAT, "line 2, column 18"},
        {"{\"objects\":[{%s,\"degree\":[1,1]}]}", SF_EFORMAT, NULL}, /* a key twice */
        {"{\"objects\":[{%s} 7]}", SF_EFORMAT, NULL},
        {"{\"objects\":[{%s}]", SF_EFORMAT, NULL},
        {"{\"objects\":[{%s,\"name\":\"a]},{\\\"\"}, 7]}", SF_EINVAL, "/objects/1"},
        {"{\"patches\":[{%s}],\"objects\":5}", SF_EINVAL, "/objects"},
        {"{\"objects\":[{%s}],\n \"image\": {\"width\" 8}}", SF_EFORMAT, "line 2, column 20"},
    };
    for (size_t k = 0; k < sizeof cases / sizeof *cases; k++) {
        snprintf(buf, sizeof buf, cases[k].body, obj);
        struct sf_err err;
        int rc = parse(buf, SCENE_JSON, &err, NULL);
        bool ok = rc == cases[k].code && (!cases[k].pointer || !strcmp(err.pointer, cases[k].pointer)) && err.message[0];
        if (!ok)
            fprintf(stderr, "  case %zu (%s): rc %d pointer \"%s\" message \"%s\"\n", k, buf, rc, err.pointer, err.message);
        CHECK(ok);
    }
}

TEST(bad_text_scenes)
{
    struct {
        const char *body;
        enum scene_format fmt;
        int code;
    } cases[] = {
        {"x", SCENE_BPT, SF_EFORMAT},
        {"2\n3 3\n0 0 0\n", SCENE_BPT, SF_EFORMAT},
        {"1\n99 3\n", SCENE_BPT, SF_EFORMAT},
        {"1\n1 1\n0 0 0\n1 0 0\n0 1 0\n1 1 1\n junk", SCENE_BPT, SF_EFORMAT},
        {"1\n1 1\n0 0 0\n1 0 0\n0 1 0\n1 1 nan\n", SCENE_BPT, SF_EFORMAT},
        {"uOrder 2 vOrder 2 uDimension 2 vDimension 2 uKnot [0 0 1 1] vKnot [0 0 1 1] controlPoint [0 0 0, 1 0 0]",
         SCENE_VRML, SF_EINVAL},
        {"uOrder 2 vOrder 2 uDimension 2 vDimension 2 uKnot [0 0 1] vKnot [0 0 1 1] "
         "controlPoint [0 0 0, 1 0 0, 0 1 0, 1 1 1]", SCENE_VRML, SF_EINVAL},
        {"uOrder 2 vOrder 2 uDimension 2 vDimension 2 uKnot [0 0 1 1 vKnot", SCENE_VRML, SF_EFORMAT},
        {"uOrder 2 bogusField 3", SCENE_VRML, SF_EFORMAT},
        {"", SCENE_VRML, SF_EFORMAT},
        {"uOrder 99", SCENE_VRML, SF_EFORMAT},
    };
    for (size_t k = 0; k < sizeof cases / sizeof *cases; k++) {
        struct sf_err err;
        int rc = parse(cases[k].body, cases[k].fmt, &err, NULL);
        if (rc != cases[k].code || !err.message[0])
            fprintf(stderr, "  case %zu: rc %d (%s at %s)\n", k, rc, err.message, err.pointer);
        CHECK(rc == cases[k].code && err.message[0]);
    }
}

int main(void)
{
    RUN(shared_scenes_parse);
    RUN(bpt_equals_json);
    RUN(vrml_order_and_concatenation);
    RUN(json_options);
    RUN(bad_json_scenes);
    RUN(bad_text_scenes);
    UNIT_END();
}
