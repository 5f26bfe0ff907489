/* test_iges.c - the IGES reader's poll (api/iges.h): a real part is polled between its surfaces
 * with a share done that only grows and ends near 1, and a cancel at any of those polls stops the
 * parse with SF_ECANCEL and nothing left held (the sanitizer's leak check). The budget itself is
 * tested over HTTP (tests/api/iges_budget.sh). */
#include "../../api/iges.h"
#include "../unit.h"

struct polls {
    int n, stop_at; /* calls so far; answer stop at call stop_at (0: never) */
    double last;
    bool backwards;
};

static bool poll(void *ctx, double done)
{
    struct polls *p = ctx;
    p->n++;
    p->backwards |= done < p->last || done > 1;
    p->last = done;
    return p->n == p->stop_at;
}

TEST(poll_and_cancel)
{
    size_t len;
    char *buf = unit_data("scenes", "mug_solid.igs", &len);
    REQUIRE(buf != NULL);
    struct polls all = {0};
    struct sf_progress pr = {poll, &all};
    struct scene sc;
    struct sf_err err = {0};
    REQUIRE(iges_parse(buf, len, &pr, &sc, &err) == 0);
    CHECK(sc.n_objects == 13);
    scene_free(&sc);
    CHECK(all.n >= 11 + 13); /* each of its 11 143s counted, then each of its 13 surfaces made */
    CHECK(!all.backwards);
    CHECK(all.last > 0.9); /* the loops made are nearly all the count said */
    for (int k = 1; k <= all.n; k++) {
        struct polls cut = {0, k, 0, false};
        struct sf_progress cpr = {poll, &cut};
        memset(&err, 0, sizeof err);
        int rc = iges_parse(buf, len, &cpr, &sc, &err);
        if (rc != SF_ECANCEL)
            fprintf(stderr, "  cancel at poll %d: rc %d (%s)\n", k, rc, err.message);
        CHECK(rc == SF_ECANCEL && err.code == SF_ECANCEL);
    }
    free(buf);
}

int main(void)
{
    RUN(poll_and_cancel);
    UNIT_END();
}
