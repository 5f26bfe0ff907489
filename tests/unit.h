/* unit.h - the test harness: TEST(name) functions listed in a main via RUN(name); checks with
 * tolerances. Each binary ends with "N passed, N failed" counting test cases. Header-only. */
#ifndef SURFD_UNIT_H
#define SURFD_UNIT_H

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static int unit_failed_checks, unit_passed, unit_failed;

#define CHECK(cond)                                                                   \
    do {                                                                              \
        if (!(cond)) {                                                                \
            fprintf(stderr, "  %s:%d: CHECK(%s) failed\n", __FILE__, __LINE__, #cond); \
            unit_failed_checks++;                                                     \
        }                                                                             \
    } while (0)

/* CHECK, and the test case goes no further when it fails: what follows would read what was never
 * made (a data file that is missing, a parse that failed). */
#define REQUIRE(cond)                                                                   \
    do {                                                                                \
        if (!(cond)) {                                                                  \
            fprintf(stderr, "  %s:%d: REQUIRE(%s) failed\n", __FILE__, __LINE__, #cond); \
            unit_failed_checks++;                                                       \
            return;                                                                     \
        }                                                                               \
    } while (0)

#define CHECK_NEAR(a, b, tol)                                                                    \
    do {                                                                                         \
        double unit_a = (a), unit_b = (b);                                                       \
        if (!(fabs(unit_a - unit_b) <= (tol))) {                                                 \
            fprintf(stderr, "  %s:%d: %s = %.17g, expected %s = %.17g (tol %g)\n", __FILE__, __LINE__, \
                    #a, unit_a, #b, unit_b, (double)(tol));                                      \
            unit_failed_checks++;                                                                \
        }                                                                                        \
    } while (0)

#define CHECK_STR(a, b) CHECK(strcmp((a), (b)) == 0)

/* Reads $SURFD_DATA/sub/name (default ../shared/data) whole; NULL when missing. Caller frees. */
__attribute__((unused)) static char *unit_data(const char *sub, const char *name, size_t *len)
{
    const char *dir = getenv("SURFD_DATA");
    char path[512];
    snprintf(path, sizeof path, "%s/%s/%s", dir ? dir : "../shared/data", sub, name);
    FILE *f = fopen(path, "rb");
    if (!f) {
        fprintf(stderr, "  cannot open %s\n", path);
        return NULL;
    }
    fseek(f, 0, SEEK_END);
    long n = ftell(f);
    fseek(f, 0, SEEK_SET);
    char *buf = n >= 0 ? malloc((size_t)n + 1) : NULL;
    *len = buf ? fread(buf, 1, (size_t)n, f) : 0;
    if (buf)
        buf[*len] = 0;
    fclose(f);
    return buf;
}

#define TEST(name) static void test_##name(void)

#define RUN(name)                                            \
    do {                                                     \
        int unit_before = unit_failed_checks;                \
        test_##name();                                       \
        if (unit_failed_checks == unit_before) {             \
            unit_passed++;                                   \
        } else {                                             \
            unit_failed++;                                   \
            fprintf(stderr, "FAIL %s\n", #name);             \
        }                                                    \
    } while (0)

#define UNIT_END()                                                \
    do {                                                          \
        printf("%d passed, %d failed\n", unit_passed, unit_failed); \
        return unit_failed ? 1 : 0;                               \
    } while (0)

#endif
