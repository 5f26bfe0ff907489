/* test_memwrap.c - the allocator wrappers (daemon/memwrap.c), linked with the daemon's --wrap
 * flags: what a job's thread allocates is charged to its account and what it frees credited, to
 * the byte, through every path (malloc, calloc, realloc growing, shrinking, moving, to 0, strdup);
 * past the budget an allocation fails as malloc fails and nothing is charged; jansson's are charged
 * but never refused; threads of other accounts (or none) are charged nothing. */
#include <jansson.h>
#include <pthread.h>

#include "../../core/base/mem.h"
#include "../unit.h"

static long long held(const struct mem_account *a) { return atomic_load(&a->held); }

/* allocations the test only frees: seen here, or the compiler drops the pair */
static void *volatile seen;

TEST(charged_and_credited_to_the_byte)
{
    struct mem_account a = {0};
    mem_account_enter(&a);
    char *p = malloc(100);
    CHECK(p && held(&a) >= 100);
    char *q = seen = calloc(10, 1000);
    CHECK(q && held(&a) >= 10100);
    p = realloc(p, 1 << 20); /* grows, moves */
    CHECK(p && held(&a) >= (1 << 20) + 10000);
    p = realloc(p, 10); /* shrinks */
    CHECK(p && held(&a) < 20000);
    char *s = strdup("a name of some length");
    CHECK(s && !strcmp(s, "a name of some length"));
    free(s);
    free(q);
    CHECK(realloc(p, 0) == NULL); /* glibc frees it */
    CHECK(held(&a) == 0 && atomic_load(&a.peak) >= (1 << 20) && atomic_load(&a.refused) == 0);
    mem_account_enter(NULL);
}

TEST(refused_past_the_budget)
{
    struct mem_account a = {.budget = 1 << 20};
    mem_account_enter(&a);
    char *p = malloc(1000);
    REQUIRE(p);
    long long before = held(&a);
    CHECK(malloc(2 << 20) == NULL && atomic_load(&a.refused) == 2 << 20 && held(&a) == before);
    CHECK(calloc(1 << 19, 4) == NULL && held(&a) == before);
    volatile size_t huge = (size_t)-1 / 2; /* (not a constant: the compiler would refuse it) */
    CHECK(calloc(huge, 4) == NULL); /* the product wraps */
    strcpy(p, "kept");
    void *(*volatile re)(void *, size_t) = realloc; /* (the compiler warns of p's use after any realloc) */
    CHECK(re(p, 4 << 20) == NULL && !strcmp(p, "kept") && held(&a) == before); /* p kept, as realloc keeps it */
    char *big = malloc(900000); /* under the budget with p */
    CHECK(big && malloc(200000) == NULL);
    free(big);
    free(p);
    CHECK(held(&a) == 0);
    mem_account_enter(NULL);
}

TEST(jansson_charged_never_refused)
{
    struct mem_account a = {.budget = 1 << 20};
    mem_account_enter(&a);
    json_t *small = json_loads("[1, 2, 3, {\"a\": \"b\"}]", 0, NULL);
    CHECK(small && held(&a) > 0);
    json_decref(small);
    CHECK(held(&a) == 0);
    json_t *big = json_array(); /* a tree past the budget: jansson is never refused ... */
    int failed = 0;
    for (int k = 0; big && k < 100000 && !failed; k++)
        failed = json_array_append_new(big, json_integer(k));
    CHECK(big && !failed && held(&a) > (1 << 20) && atomic_load(&a.refused) == 0);
    CHECK(malloc(16) == NULL && atomic_load(&a.refused) == 16); /* ... the job's own next allocation is */
    json_decref(big);
    CHECK(held(&a) == 0);
    mem_account_enter(NULL);
}

static void *other_thread(void *arg)
{
    struct mem_account *b = arg;
    mem_account_enter(b);
    for (int k = 0; k < 1000; k++)
        free(seen = malloc(4096));
    void *kept = malloc(5000);
    mem_account_enter(NULL);
    return kept;
}

TEST(accounts_are_per_thread)
{
    struct mem_account a = {0}, b = {0};
    mem_account_enter(&a);
    void *p = seen = malloc(3000);
    pthread_t t;
    void *kept = NULL;
    REQUIRE(pthread_create(&t, NULL, other_thread, &b) == 0);
    pthread_join(t, &kept);
    CHECK(kept && held(&b) >= 5000 && held(&a) >= 3000 && held(&a) < 4096);
    free(p);
    CHECK(held(&a) == 0);
    mem_account_enter(NULL);
    free(kept); /* by a thread without an account: nobody credited */
    CHECK(held(&b) >= 5000 && held(&a) == 0);
    void *loose = seen = malloc(100); /* no account: nothing charged */
    free(loose);
    CHECK(held(&a) == 0);
}

int main(void)
{
    RUN(charged_and_credited_to_the_byte);
    RUN(refused_past_the_budget);
    RUN(jansson_charged_never_refused);
    RUN(accounts_are_per_thread);
    UNIT_END();
}
