/* mem.h - the one growable-array helper of core/. */
#ifndef SURFD_MEM_H
#define SURFD_MEM_H

#include <stddef.h>

/* Grows *p (holding *cap elements of size elem) to hold at least need elements, doubling.
 * Returns 0, or SF_ENOMEM leaving *p and *cap as they were. */
int mem_reserve(void **p, size_t *cap, size_t need, size_t elem);

#endif
