/* test_frep_json.c - FRep requests (api/frep_json.h): the API.md example, the grid it makes, lists
 * as balanced trees, and every kind of bad tree answered with its code and JSON pointer. */
#include "../../api/frep_json.h"

#include <stdbool.h>

#include "../unit.h"

static int parse(const char *text, struct frep_request *r, struct sf_err *err)
{
    memset(err, 0, sizeof *err);
    return frep_parse(text, strlen(text), r, err);
}

/* text is refused with code at pointer */
static bool refused(const char *text, int code, const char *pointer)
{
    struct frep_request r;
    struct sf_err err;
    int rc = parse(text, &r, &err);
    if (rc == 0)
        frep_request_free(&r);
    if (rc != code || strcmp(err.pointer, pointer)) {
        fprintf(stderr, "  %s\n    -> %d at \"%s\" (%s), expected %d at \"%s\"\n", text, rc, err.pointer, err.message,
                code, pointer);
        return false;
    }
    return true;
}

static int depth(const struct frep *f, int at)
{
    const struct frep_node *n = &f->nodes[at];
    if (n->kind < FREP_UNION)
        return 1;
    int a = depth(f, n->a), b = n->kind <= FREP_BLEND ? depth(f, n->b) : 0;
    return 1 + (a > b ? a : b);
}

TEST(the_api_example)
{
    const char *text =
        "{\"name\": \"bracket\", \"bounds\": [[-2, -2, -2], [2, 2, 2]], \"cell\": 0.02, \"alpha\": 0,"
        " \"frep\": {\"subtract\": ["
        "   {\"union\": [{\"box\": {\"min\": [-1, -1, -1], \"max\": [1, 1, 1]}},"
        "              {\"cylinder\": {\"base\": [0, 0, -1.5], \"axis\": [0, 0, 2], \"radius\": 0.5, \"length\": 3}}]},"
        "   {\"transform\": {\"translate\": [1, 1, 1], \"rotate_deg\": [0, 0, 45], \"scale\": [1, 1, 1],"
        "                  \"object\": {\"sphere\": {\"center\": [0, 0, 0], \"radius\": 0.6}}}}]}}";
    struct frep_request r;
    struct sf_err err;
    CHECK(parse(text, &r, &err) == 0);
    CHECK_STR(r.name, "bracket");
    CHECK(r.dims[0] == 201 && r.dims[1] == 201 && r.dims[2] == 201);
    CHECK(r.f.n == 6);
    CHECK(r.f.nodes[r.f.root].kind == FREP_SUBTRACT);
    CHECK_NEAR(r.f.nodes[1].p[5], 1, 1e-15); /* the cylinder's axis, made a unit vector */
    double in[3] = {0, 0, 0}, out[3] = {0.9, 0.9, 0.9}, cyl[3] = {0, 0, 1.4}, far[3] = {0, 0, 1.6};
    CHECK(frep_eval(&r.f, in, NULL) > 0);
    CHECK(frep_eval(&r.f, out, NULL) < 0); /* the sphere took the corner */
    CHECK(frep_eval(&r.f, cyl, NULL) > 0);
    CHECK(frep_eval(&r.f, far, NULL) < 0);
    frep_request_free(&r);
}

/* volume primitives: one reference a model, however often the tree reads it */
TEST(volumes_are_referenced_once_each)
{
    struct frep_request r;
    struct sf_err err;
    const char *text = "{\"bounds\": [[0, 0, 0], [1, 1, 1]], \"cell\": 0.1, \"frep\": {\"union\": ["
                       "{\"volume\": {\"model\": \"0123456789abcdef0123456789abcdef\", \"scale\": 0.01}},"
                       "{\"volume\": {\"model\": \"00000000000000000000000000000001\"}},"
                       "{\"volume\": {\"model\": \"0123456789abcdef0123456789abcdef\"}}]}}";
    CHECK(parse(text, &r, &err) == 0);
    CHECK(r.n_refs == 2 && !strcmp(r.refs[1].model, "00000000000000000000000000000001"));
    CHECK(!strcmp(r.refs[0].pointer, "/frep/union/0/volume/model"));
    frep_volume_iso(&r, 0, 226.5);
    int reads0 = 0;
    for (int i = 0; i < r.f.n; i++)
        if (r.f.nodes[i].kind == FREP_VOLUME && r.f.nodes[i].p[0] == 0) {
            CHECK(r.f.nodes[i].p[1] == 226.5);
            reads0++;
        }
    CHECK(reads0 == 2);
    frep_request_free(&r);
}

TEST(lists_are_balanced)
{
    static char text[100000];
    int n = snprintf(text, sizeof text, "{\"bounds\": [[0, 0, 0], [1, 1, 1]], \"cell\": 0.1, \"frep\": {\"union\": [");
    for (int k = 0; k < 1000; k++)
        n += snprintf(text + n, sizeof text - n, "%s{\"sphere\": {\"center\": [%d, 0, 0], \"radius\": 0.5}}", k ? "," : "", k);
    snprintf(text + n, sizeof text - n, "], \"alpha\": 1}}");
    struct frep_request r;
    struct sf_err err;
    CHECK(parse(text, &r, &err) == 0);
    CHECK(r.f.n == 1999);
    CHECK(depth(&r.f, r.f.root) == 11); /* ceil(log2 1000) + 1 */
    double x[3] = {700, 0.25, 0};
    CHECK_NEAR(frep_eval(&r.f, x, NULL), 0.25, 1e-12); /* alpha 1: the max of the distances */
    frep_request_free(&r);
}

TEST(bad_trees)
{
#define REQ(tree) "{\"bounds\": [[0, 0, 0], [1, 1, 1]], \"cell\": 0.1, \"frep\": " tree "}"
#define SPHERE "{\"sphere\": {\"center\": [0, 0, 0], \"radius\": 1}}"
    CHECK(refused("{\"bounds\": [[0, 0", SF_EFORMAT, "line 1, column 17"));
    CHECK(refused("[1]", SF_EINVAL, ""));
    CHECK(refused("{\"bounds\": [[0, 0, 0], [1, 1, 1]], \"cell\": 0.1}", SF_EINVAL, "/frep"));
    CHECK(refused("{\"bounds\": [[0, 0, 0], [1, 1, 1]], \"cell\": 0.1, \"frep\": " SPHERE ", \"colour\": 1}", SF_EINVAL,
                  "/colour"));
    CHECK(refused(REQ("{\"blob\": {}}"), SF_EINVAL, "/frep/blob"));
    CHECK(refused(REQ("{\"subtract\": [" SPHERE ", {\"sphere\": {\"center\": [0, 0, 0], \"radius\": -1}}]}"), SF_EINVAL,
                  "/frep/subtract/1/sphere/radius"));
    CHECK(refused(REQ("{\"sphere\": {\"center\": [0, 0, 0], \"radus\": 1}}"), SF_EINVAL, "/frep/sphere/radus"));
    CHECK(refused(REQ("{\"sphere\": {\"center\": [0, 0], \"radius\": 1}}"), SF_EINVAL, "/frep/sphere/center"));
    CHECK(refused(REQ("{\"sphere\": {\"center\": [0, \"a\", 0], \"radius\": 1}}"), SF_EINVAL, "/frep/sphere/center/1"));
    CHECK(refused(REQ("{\"union\": [" SPHERE "], \"alpha\": 1.5}"), SF_EINVAL, "/frep/alpha"));
    CHECK(refused("{\"bounds\": [[0, 0, 0], [1, 1, 1]], \"cell\": 0.1, \"alpha\": -0.1, \"frep\": " SPHERE "}", SF_EINVAL,
                  "/alpha"));
    CHECK(refused(REQ("{\"box\": {\"min\": [0, 0, 0], \"max\": [1, 0, 1]}}"), SF_EINVAL, "/frep/box/max/1"));
    CHECK(refused(REQ("{\"cylinder\": {\"base\": [0, 0, 0], \"axis\": [0, 0, 0], \"radius\": 1, \"length\": 1}}"),
                  SF_EINVAL, "/frep/cylinder/axis"));
    CHECK(refused(REQ("{\"cone\": {\"base\": [0, 0, 0], \"axis\": [0, 0, 1], \"radius\": 1}}"), SF_EINVAL,
                  "/frep/cone/length"));
    CHECK(refused(REQ("{\"superellipsoid\": {\"center\": [0, 0, 0], \"radii\": [1, 1, 1], \"e1\": 0, \"e2\": 1}}"),
                  SF_EINVAL, "/frep/superellipsoid/e1"));
    CHECK(refused(REQ("{\"ellipsoid\": {\"center\": [0, 0, 0], \"radii\": [1, 0, 1]}}"), SF_EINVAL,
                  "/frep/ellipsoid/radii/1"));
    CHECK(refused(REQ("{\"blend\": [" SPHERE "," SPHERE "," SPHERE "], \"a0\": 1, \"a1\": 1, \"a2\": 1}"), SF_EINVAL,
                  "/frep/blend"));
    CHECK(refused(REQ("{\"blend\": [" SPHERE "," SPHERE "], \"a0\": 1, \"a1\": 0, \"a2\": 1}"), SF_EINVAL, "/frep/a1"));
    CHECK(refused(REQ("{\"subtract\": [" SPHERE "]}"), SF_EINVAL, "/frep/subtract"));
    CHECK(refused(REQ("{\"transform\": {\"scale\": [1, -1, 1], \"object\": " SPHERE "}}"), SF_EINVAL,
                  "/frep/transform/scale/1"));
    CHECK(refused(REQ("{\"transform\": {\"translate\": [1, 1, 1]}}"), SF_EINVAL, "/frep/transform/object"));
    CHECK(refused(REQ("{\"offset\": {\"distance\": \"far\", \"object\": " SPHERE "}}"), SF_EINVAL,
                  "/frep/offset/distance"));
    CHECK(refused(REQ("{\"sphere\": {\"center\": [0, 0, 0], \"radius\": 1}, \"box\": {}}"), SF_EINVAL, "/frep"));
    CHECK(refused("{\"bounds\": [[0, 0, 0], [1, -1, 1]], \"cell\": 0.1, \"frep\": " SPHERE "}", SF_EINVAL,
                  "/bounds/1/1"));
    CHECK(refused("{\"bounds\": [[0, 0, 0]], \"cell\": 0.1, \"frep\": " SPHERE "}", SF_EINVAL, "/bounds"));
    CHECK(refused("{\"bounds\": [[0, 0, 0], [1, 1, 1]], \"cell\": 0, \"frep\": " SPHERE "}", SF_EINVAL, "/cell"));
    CHECK(refused(REQ("{\"volume\": {\"model\": \"xyz\"}}"), SF_EINVAL, "/frep/volume/model"));
    CHECK(refused(REQ("{\"volume\": {}}"), SF_EINVAL, "/frep/volume/model"));
    CHECK(refused(REQ("{\"volume\": {\"model\": \"0123456789abcdef0123456789abcdef\", \"scale\": 0}}"), SF_EINVAL,
                  "/frep/volume/scale"));
    CHECK(refused(REQ("{\"volume\": {\"model\": \"0123456789abcdef0123456789abcdef\", \"iso\": 3}}"), SF_EINVAL,
                  "/frep/volume/iso"));
    char many[4000] = "", *q = many;
    q += sprintf(q, "{\"bounds\": [[0, 0, 0], [1, 1, 1]], \"cell\": 0.1, \"frep\": {\"union\": [");
    for (int k = 0; k <= FREP_MAX_VOLUMES; k++)
        q += sprintf(q, "%s{\"volume\": {\"model\": \"%032x\"}}", k ? ", " : "", k);
    sprintf(q, "]}}");
    char at[64];
    snprintf(at, sizeof at, "/frep/union/%d/volume/model", FREP_MAX_VOLUMES);
    CHECK(refused(many, SF_ELIMIT, at));
    /* the caps: the grid's samples, the tree's depth and its nodes */
    CHECK(refused("{\"bounds\": [[0, 0, 0], [10, 10, 10]], \"cell\": 0.01, \"frep\": " SPHERE "}", SF_ELIMIT, "/cell"));
    char deep[8000] = "", *p = deep;
    p += sprintf(p, "{\"bounds\": [[0, 0, 0], [1, 1, 1]], \"cell\": 0.1, \"frep\": ");
    for (int k = 0; k < FREP_MAX_DEPTH; k++)
        p += sprintf(p, "{\"offset\": {\"distance\": 0, \"object\": ");
    p += sprintf(p, SPHERE);
    for (int k = 0; k < FREP_MAX_DEPTH; k++)
        p += sprintf(p, "}}");
    sprintf(p, "}");
    struct frep_request r;
    struct sf_err err;
    CHECK(parse(deep, &r, &err) == SF_ELIMIT && strstr(err.message, "deep"));
    static char wide[400000];
    int n = snprintf(wide, sizeof wide, "{\"bounds\": [[0, 0, 0], [1, 1, 1]], \"cell\": 0.1, \"frep\": {\"union\": [");
    for (int k = 0; k < 3000; k++)
        n += snprintf(wide + n, sizeof wide - n, "%s" SPHERE, k ? "," : "");
    snprintf(wide + n, sizeof wide - n, "]}}");
    CHECK(parse(wide, &r, &err) == SF_ELIMIT && strstr(err.message, "nodes"));
}

int main(void)
{
    RUN(the_api_example);
    RUN(lists_are_balanced);
    RUN(volumes_are_referenced_once_each);
    RUN(bad_trees);
    UNIT_END();
}
