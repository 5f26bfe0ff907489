/* srgb.c - the linear-to-sRGB table, built from the 255 thresholds between 8-bit codes (code s
 * begins where the encoded value reaches s - 1/2): 255 pow() calls, not 16 385. */
#include "srgb.h"

#include <math.h>

static double srgb_to_linear(double s)
{
    return s <= 0.04045 ? s / 12.92 : pow((s + 0.055) / 1.055, 2.4);
}

void srgb_table_init(struct srgb_table *t)
{
    int s = 0;
    double next = srgb_to_linear(0.5 / 255.0) * (SRGB_N - 1); /* code 1's threshold, in table steps */
    for (int k = 0; k < SRGB_N; k++) {
        while (s < 255 && k >= next)
            next = ++s < 255 ? srgb_to_linear((s + 0.5) / 255.0) * (SRGB_N - 1) : INFINITY;
        t->code[k] = (unsigned char)s;
    }
}
