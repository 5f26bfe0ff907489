/* mem.c - growable arrays. */
#include "mem.h"

#include <stdint.h>
#include <stdlib.h>

#include "err.h"

int mem_reserve(void **p, size_t *cap, size_t need, size_t elem)
{
    if (need <= *cap)
        return 0;
    size_t nc = *cap ? *cap : 64;
    while (nc < need)
        nc *= 2;
    if (nc > SIZE_MAX / elem)
        return SF_ENOMEM;
    void *q = realloc(*p, nc * elem);
    if (!q)
        return SF_ENOMEM;
    *p = q;
    *cap = nc;
    return 0;
}
