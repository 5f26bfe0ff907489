/* shares.c - the owners' upload ledger (shares.h): one slot an owner, under one mutex. */
#include "shares.h"

#include <pthread.h>
#include <stdlib.h>
#include <string.h>

struct slot {
    const char *name;        /* the token's (borrowed from the tokens) */
    long long arriving;      /* bytes of uploads being received */
    long long stored;        /* bytes of its stored uploads, as of the last refresh and since */
    long long since;         /* stored since the refresh began: kept over it (counted twice at worst) */
    long long fresh;         /* the refresh's sum, while it runs */
};

struct shares {
    pthread_mutex_t lock;
    size_t n;
    struct slot slot[];      /* one a distinct name; the last for open mode ("") and unknown names */
};

struct shares *shares_new(const struct token *tokens, size_t n)
{
    struct shares *sh = calloc(1, sizeof *sh + (n + 1) * sizeof *sh->slot);
    if (!sh)
        return NULL;
    pthread_mutex_init(&sh->lock, NULL);
    for (size_t k = 0; k < n; k++) {
        size_t j = 0;
        while (j < sh->n && strcmp(sh->slot[j].name, tokens[k].name))
            j++;
        if (j == sh->n)
            sh->slot[sh->n++].name = tokens[k].name;
    }
    sh->slot[sh->n].name = "";
    return sh;
}

void shares_free(struct shares *sh)
{
    if (sh)
        pthread_mutex_destroy(&sh->lock);
    free(sh);
}

/* owner's slot (lock held) */
static struct slot *slot_of(struct shares *sh, const char *owner)
{
    for (size_t k = 0; k < sh->n; k++)
        if (!strcmp(sh->slot[k].name, owner))
            return &sh->slot[k];
    return &sh->slot[sh->n];
}

bool shares_take(struct shares *sh, const char *owner, long long bytes, long long share, long long *held)
{
    pthread_mutex_lock(&sh->lock);
    struct slot *s = slot_of(sh, owner);
    *held = s->arriving + s->stored;
    bool fits = *held + bytes <= share;
    if (fits)
        s->arriving += bytes;
    pthread_mutex_unlock(&sh->lock);
    return fits;
}

void shares_give(struct shares *sh, const char *owner, long long bytes)
{
    pthread_mutex_lock(&sh->lock);
    slot_of(sh, owner)->arriving -= bytes;
    pthread_mutex_unlock(&sh->lock);
}

void shares_stored(struct shares *sh, const char *owner, long long bytes)
{
    pthread_mutex_lock(&sh->lock);
    struct slot *s = slot_of(sh, owner);
    s->stored += bytes;
    s->since += bytes;
    pthread_mutex_unlock(&sh->lock);
}

static void add_fresh(const char *owner, long long bytes, void *arg)
{
    slot_of(arg, owner)->fresh += bytes; /* the lock is not held: only the refresh writes fresh */
}

int shares_refresh(struct shares *sh, struct store *store)
{
    pthread_mutex_lock(&sh->lock);
    for (size_t k = 0; k <= sh->n; k++)
        sh->slot[k].since = sh->slot[k].fresh = 0;
    pthread_mutex_unlock(&sh->lock);
    int rc = store_uploads_held(store, add_fresh, sh);
    pthread_mutex_lock(&sh->lock);
    for (size_t k = 0; rc == 0 && k <= sh->n; k++)
        sh->slot[k].stored = sh->slot[k].fresh + sh->slot[k].since;
    pthread_mutex_unlock(&sh->lock);
    return rc;
}
