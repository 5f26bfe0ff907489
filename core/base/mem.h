/* mem.h - the one growable-array helper of core/, and the account that charges a job's
 * allocations to its memory budget. */
#ifndef SURFD_MEM_H
#define SURFD_MEM_H

#include <stdatomic.h>
#include <stdbool.h>
#include <stddef.h>

/* Grows *p (holding *cap elements of size elem) to hold at least need elements, doubling.
 * Returns 0, or SF_ENOMEM leaving *p and *cap as they were. */
int mem_reserve(void **p, size_t *cap, size_t need, size_t elem);

/* A job's memory account. The daemon links its code with malloc, calloc, realloc, strdup and free
 * wrapped (daemon/memwrap.c): while a thread works for a job (mem_account_enter), what those
 * allocate is charged to the job's account and what they free is credited, and an allocation that
 * would take the account past its budget fails as malloc fails (NULL: SF_ENOMEM to core/), so a
 * job that outgrows its estimate ends alone with its problem instead of the kernel killing the
 * node. jansson's allocations are charged too, never refused (memwrap.c says why); what DCMTK and
 * Embree allocate for themselves is not charged (DCMTK does not expect new to throw); memory
 * freed by a thread of another account is credited there (an account may go below 0). */
struct mem_account {
    atomic_llong held;    /* bytes allocated for the job and not freed */
    atomic_llong peak;
    atomic_llong refused; /* the size of the last allocation refused for the budget; 0: none */
    long long budget;     /* bytes; 0: none */
    atomic_llong allocs;  /* allocations charged (refused ones too), counted while fail_at is set */
    long long fail_at;    /* the allocation (1, 2 ...) to refuse whatever the budget: the torture
                           * tests' (tests/fuzz/torture.sh; LLONG_MAX: only count); 0: none, and
                           * nothing counted (the jobs' allocations pay no more than held's add) */
};

/* Charges this thread's allocations to a (NULL: to none) until the next call; returns the
 * account charged before. Cheap: a thread-local pointer. */
struct mem_account *mem_account_enter(struct mem_account *a);
struct mem_account *mem_account_current(void);

/* For the wrappers: charges n bytes to this thread's account, or returns false (nothing charged,
 * the refusal recorded) when they would take it past its budget; true without an account. */
bool mem_charge(size_t n);
/* Adds delta (< 0: a credit) to this thread's account whatever its budget: what a free gives
 * back, or an allocator's rounding of what mem_charge charged. */
void mem_adjust(long long delta);

#endif
