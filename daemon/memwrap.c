/* memwrap.c - the daemon's allocator wrappers, linked with -Wl,--wrap=malloc (and calloc, realloc,
 * strdup, free: the Makefile's MEMWRAP), so that every allocation of surfd's own code (core/, api/,
 * daemon/) is charged to the memory account of the job its thread works for (core/base/mem.h),
 * and refused past the job's budget. Written by hand: glibc has no per-thread allocation hooks
 * any more, and an arena per job (or a second allocator) would change where every free goes.
 * The cost without an account is a thread-local load; with one, malloc_usable_size and an atomic
 * add per call. Sizes are charged as the allocator rounds them (malloc_usable_size), so what is
 * charged on allocation is what free credits. */
#include <jansson.h>
#include <malloc.h>
#include <string.h>

#include "../core/base/mem.h"

void *__real_malloc(size_t n);
void *__real_calloc(size_t k, size_t n);
void *__real_realloc(void *p, size_t n);
void __real_free(void *p);
void *__wrap_malloc(size_t n);
void *__wrap_calloc(size_t k, size_t n);
void *__wrap_realloc(void *p, size_t n);
char *__wrap_strdup(const char *s);
void __wrap_free(void *p);

/* Settles a request of n bytes, charged: to what the allocator gave (p NULL: nothing). */
static void *settle(void *p, size_t n)
{
    mem_adjust(p ? (long long)malloc_usable_size(p) - (long long)n : -(long long)n);
    return p;
}

void *__wrap_malloc(size_t n)
{
    if (!mem_account_current())
        return __real_malloc(n);
    return mem_charge(n) ? settle(__real_malloc(n), n) : NULL;
}

void *__wrap_calloc(size_t k, size_t n)
{
    if (!mem_account_current())
        return __real_calloc(k, n);
    if (n && k > (size_t)-1 / n)
        return NULL;
    return mem_charge(k * n) ? settle(__real_calloc(k, n), k * n) : NULL;
}

void *__wrap_realloc(void *p, size_t n)
{
    if (!mem_account_current())
        return __real_realloc(p, n);
    if (!p)
        return __wrap_malloc(n);
    if (!n) { /* glibc frees p */
        __wrap_free(p);
        return NULL;
    }
    size_t had = malloc_usable_size(p);
    if (n > had && !mem_charge(n - had))
        return NULL; /* p kept, as realloc keeps it when it fails */
    void *q = __real_realloc(p, n);
    long long charged = n > had ? (long long)n : (long long)had; /* held for p now */
    mem_adjust((q ? (long long)malloc_usable_size(q) : (long long)had) - charged);
    return q;
}

char *__wrap_strdup(const char *s)
{
    size_t n = strlen(s) + 1;
    char *d = __wrap_malloc(n);
    return d ? memcpy(d, s, n) : NULL;
}

void __wrap_free(void *p)
{
    if (p && mem_account_current())
        mem_adjust(-(long long)malloc_usable_size(p));
    __real_free(p);
}

/* jansson allocates inside its own library, where --wrap does not reach: its allocations (a JSON
 * tree a job parses) are charged to the job too, but never refused, since jansson 2.14 does not
 * survive a failed allocation in the middle of a parse (its lexer drops the failure and walks past
 * its buffer: jansson issue #362; found by tests/fuzz/torture.sh). What it holds counts against
 * the budget, so the job's own next allocation is refused instead. Set before main, so that
 * nothing jansson frees was allocated otherwise. */
static void *jansson_malloc(size_t n)
{
    void *p = __real_malloc(n);
    if (p && mem_account_current())
        mem_adjust((long long)malloc_usable_size(p));
    return p;
}

__attribute__((constructor)) static void charge_jansson(void) { json_set_alloc_funcs(jansson_malloc, __wrap_free); }
