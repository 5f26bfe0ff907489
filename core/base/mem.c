/* mem.c - growable arrays, and the memory accounts of jobs (mem.h). */
#include "mem.h"

#include <limits.h>
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

static _Thread_local struct mem_account *current;

struct mem_account *mem_account_enter(struct mem_account *a)
{
    struct mem_account *was = current;
    current = a;
    return was;
}

struct mem_account *mem_account_current(void) { return current; }

static bool refuse(struct mem_account *a, long long n)
{
    atomic_store_explicit(&a->refused, n, memory_order_relaxed);
    return false;
}

static void note_peak(struct mem_account *a, long long held)
{
    long long peak = atomic_load_explicit(&a->peak, memory_order_relaxed);
    while (held > peak && !atomic_compare_exchange_weak_explicit(&a->peak, &peak, held, memory_order_relaxed,
                                                                 memory_order_relaxed))
        ;
}

bool mem_charge(size_t n)
{
    struct mem_account *a = current;
    if (!a)
        return true;
    if (a->fail_at && atomic_fetch_add_explicit(&a->allocs, 1, memory_order_relaxed) + 1 == a->fail_at)
        return refuse(a, n > (size_t)LLONG_MAX ? LLONG_MAX : (long long)n); /* (counted for tests only) */
    if (a->budget && n > (size_t)a->budget)
        return refuse(a, n > (size_t)LLONG_MAX ? LLONG_MAX : (long long)n);
    long long m = (long long)n; /* under a budget, or from an allocator that cannot give 2^63 */
    long long held = atomic_fetch_add_explicit(&a->held, m, memory_order_relaxed) + m;
    if (a->budget && held > a->budget) {
        atomic_fetch_sub_explicit(&a->held, m, memory_order_relaxed);
        return refuse(a, m);
    }
    note_peak(a, held);
    return true;
}

void mem_adjust(long long delta)
{
    struct mem_account *a = current;
    if (a)
        note_peak(a, atomic_fetch_add_explicit(&a->held, delta, memory_order_relaxed) + delta);
}
