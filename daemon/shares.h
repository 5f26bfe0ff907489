/* shares.h - each owner's share of the data dir for uploads (upload-share): the bytes of its
 * streamed bodies arriving now, and of those stored for its jobs not yet ended. An upload is
 * decided from its headers (Content-Length) before any byte of it is written, on an HTTP thread,
 * so without a store query: the stored part is read from the store by the keeper
 * (shares_refresh, every few seconds) and grows at once when an upload is stored.
 *
 * The owners are the token file's names (one share for all in open mode). An ended job's body is
 * removed by the next prune (store.h), so a share frees itself as its owner's jobs end. */
#ifndef SURFD_SHARES_H
#define SURFD_SHARES_H

#include <stdbool.h>
#include <stddef.h>

#include "store.h"
#include "tokens.h"

struct shares;

/* A ledger for the owners of tokens[0..n) (none: open mode). NULL when out of memory. */
struct shares *shares_new(const struct token *tokens, size_t n);
void shares_free(struct shares *sh);

/* Takes bytes more of owner's share for an upload arriving: true; or false, taking nothing, when
 * what the owner holds and bytes would be over share. *held: what the owner holds (before). */
bool shares_take(struct shares *sh, const char *owner, long long bytes, long long share, long long *held);
/* Gives back bytes an upload took (it ended: stored, refused or cut off). */
void shares_give(struct shares *sh, const char *owner, long long bytes);
/* Counts an upload the store took for owner (before shares_give of its arrival: never under). */
void shares_stored(struct shares *sh, const char *owner, long long bytes);
/* Reads what the store holds for each owner's jobs not yet ended: 0, or -1 (the figures kept). */
int shares_refresh(struct shares *sh, struct store *store);

#endif
