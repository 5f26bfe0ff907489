/* test_planes.c - a stack of image planes to one grid (api/planes.c): even stacks sorted whatever
 * their order, along a turned normal too; every refusal naming its plane (another size,
 * orientation or spacing, two at one place, a missing slice); the sparse stack of a
 * Segmentation's frames on the grid of their least distance apart, its planes off that grid
 * refused, and its span capped before anything is allocated. */
#include "../../api/planes.h"

#include "../unit.h"

/* n axial 4x3 planes, frame k at z = z0 + step * order[k] */
static void axial(struct plane *pl, int n, const int *order, double z0, double step)
{
    for (int k = 0; k < n; k++) {
        pl[k] = (struct plane){.part = 0, .frame = k, .rows = 3, .cols = 4, .pos = {-10, 5, z0 + step * order[k]},
                               .orient = {1, 0, 0, 0, 1, 0}, .spacing = {0.5, 0.75}, .tag = k};
    }
}

/* planes_layout with err cleared first (an error keeps its first failure) */
static int lay(struct plane *pl, int n, bool sparse, size_t max, struct planes_grid *g, struct sf_err *err)
{
    *err = (struct sf_err){0};
    return planes_layout(pl, n, sparse, max, g, err);
}

TEST(even_stacks_are_sorted)
{
    struct plane pl[5];
    int order[5] = {3, 0, 4, 1, 2};
    axial(pl, 5, order, -7, 2.5);
    struct planes_grid g;
    struct sf_err err = {0};
    REQUIRE(lay(pl, 5, false, 1000, &g, &err) == 0);
    CHECK(g.nx == 4 && g.ny == 3 && g.nz == 5);
    CHECK_NEAR(g.spacing[0], 0.75, 1e-12); /* columns: PixelSpacing's second value */
    CHECK_NEAR(g.spacing[1], 0.5, 1e-12);
    CHECK_NEAR(g.spacing[2], 2.5, 1e-12);
    CHECK_NEAR(g.origin[2], -7, 1e-12);
    const int want[5] = {1, 3, 4, 0, 2};
    for (int k = 0; k < 5; k++)
        CHECK(pl[k].z == k && pl[k].tag == want[k]);
    CHECK_NEAR(g.axes[2][2], 1, 1e-12);
}

TEST(a_turned_normal_sorts_along_itself)
{
    struct plane pl[3];
    int order[3] = {2, 0, 1};
    axial(pl, 3, order, 0, 1);
    for (int k = 0; k < 3; k++) { /* sagittal: rows along y, columns along -z; the normal is -x */
        double d = pl[k].pos[2];
        memcpy(pl[k].orient, (double[6]){0, 1, 0, 0, 0, -1}, sizeof pl[k].orient);
        pl[k].pos[0] = -d, pl[k].pos[2] = 0;
    }
    struct planes_grid g;
    struct sf_err err = {0};
    REQUIRE(lay(pl, 3, false, 1000, &g, &err) == 0);
    CHECK(pl[0].tag == 1 && pl[2].tag == 0); /* along -x: x = 0 first, x = -2 last */
    CHECK_NEAR(g.axes[2][0], -1, 1e-12);
}

TEST(refusals_name_the_plane)
{
    struct plane pl[4];
    int order[4] = {0, 1, 2, 3};
    struct planes_grid g;
    struct sf_err err = {0};
    axial(pl, 4, order, 0, 3);
    pl[2].rows = 5;
    CHECK(lay(pl, 4, false, 1000, &g, &err) == SF_EINVAL && !strcmp(err.pointer, "/parts/0/frames/2") &&
          strstr(err.message, "another size"));
    axial(pl, 4, order, 0, 3);
    pl[1].orient[4] = 0.99;
    CHECK(lay(pl, 4, false, 1000, &g, &err) == SF_EINVAL && strstr(err.message, "orientation"));
    axial(pl, 4, order, 0, 3);
    pl[3].spacing[0] = 0.6;
    CHECK(lay(pl, 4, false, 1000, &g, &err) == SF_EINVAL && strstr(err.message, "PixelSpacing"));
    axial(pl, 4, order, 0, 3);
    pl[2].pos[2] = pl[1].pos[2];
    CHECK(lay(pl, 4, false, 1000, &g, &err) == SF_EINVAL && strstr(err.message, "same position"));
    int gap[4] = {0, 1, 3, 4}; /* a slice missing: 3 mm, 6 mm, 3 mm, 4 on average: the first step off it named */
    axial(pl, 4, gap, 0, 3);
    CHECK(lay(pl, 4, false, 1000, &g, &err) == SF_EINVAL && !strcmp(err.pointer, "/parts/0/frames/1") &&
          strstr(err.message, "uneven"));
    axial(pl, 1, order, 0, 3);
    CHECK(lay(pl, 1, false, 1000, &g, &err) == SF_EINVAL);
    axial(pl, 2, order, 0, 3);
    pl[0].frame = pl[1].frame = -1, pl[1].part = 1;
    pl[1].cols = 9;
    CHECK(lay(pl, 2, false, 1000, &g, &err) == SF_EINVAL && !strcmp(err.pointer, "/parts/1") &&
          strstr(err.message, "a slice of another size than the first part's"));
}

TEST(sparse_stacks_leave_planes_out)
{
    struct plane pl[5];
    int order[5] = {7, 0, 1, 1, 3}; /* two segments' frames at plane 1; planes 2, 4, 5, 6 empty */
    axial(pl, 5, order, 10, 1.5);
    struct planes_grid g;
    struct sf_err err = {0};
    REQUIRE(lay(pl, 5, true, 1000, &g, &err) == 0);
    CHECK(g.nz == 8);
    CHECK_NEAR(g.spacing[2], 1.5, 1e-12);
    CHECK_NEAR(g.origin[2], 10, 1e-12);
    for (int k = 0; k < 5; k++)
        CHECK(pl[k].z == order[pl[k].tag]);
    axial(pl, 5, order, 10, 1.5);
    pl[4].pos[2] += 0.6; /* plane 3.4: off the grid */
    CHECK(lay(pl, 5, true, 1000, &g, &err) == SF_EINVAL && !strcmp(err.pointer, "/parts/0/frames/4") &&
          strstr(err.message, "not on one grid"));
    int far[2] = {0, 1};
    axial(pl, 2, far, 0, 1);
    pl[1].pos[2] = 1e5; /* 2 frames 100 m apart: a step past ranges.h's */
    CHECK(lay(pl, 2, true, 1000, &g, &err) == SF_EINVAL);
    int three[3] = {0, 1, 5000}; /* 5001 planes of 12 samples: over a cap of 1000 */
    axial(pl, 3, three, 0, 0.5);
    CHECK(lay(pl, 3, true, 1000, &g, &err) == SF_ELIMIT && strstr(err.message, "span"));
    CHECK(lay(pl, 3, true, 100000, &g, &err) == 0 && g.nz == 5001);
    int one[2] = {0, 0};
    axial(pl, 2, one, 0, 1);
    CHECK(lay(pl, 2, true, 1000, &g, &err) == SF_EINVAL && strstr(err.message, "one plane"));
}

int main(void)
{
    RUN(even_stacks_are_sorted);
    RUN(a_turned_normal_sorts_along_itself);
    RUN(refusals_name_the_plane);
    RUN(sparse_stacks_leave_planes_out);
    UNIT_END();
}
