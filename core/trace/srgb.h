/* srgb.h - linear [0, 1] colour to 8-bit sRGB (IEC 61966-2-1) through a table over 2^14 + 1
 * linear steps: a pow() per channel was most of a PNG's encoding time. 14 bits of linear input
 * keep every 8-bit code reachable (the darkest step, 1/16384, is below code 1's threshold
 * 0.5/255/12.92). Renders fill the 8-bit picture band by band, on the render's own threads. */
#ifndef SURFD_SRGB_H
#define SURFD_SRGB_H

enum { SRGB_BITS = 14, SRGB_N = (1 << SRGB_BITS) + 1 };

struct srgb_table {
    unsigned char code[SRGB_N]; /* code[k] = round(255 · srgb(k / 2^14)) */
};

void srgb_table_init(struct srgb_table *t);

static inline unsigned char srgb8(const struct srgb_table *t, float c)
{
    if (!(c > 0.0f))
        return 0; /* NaN too */
    if (c >= 1.0f)
        return 255;
    return t->code[(int)(c * (SRGB_N - 1) + 0.5f)];
}

#endif
