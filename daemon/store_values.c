/* store_values.c - what the store's callers and both backends share below the seam (store.c):
 * records freed, the volume parts a read collects, pieces named, checksums, a reaped job's state.
 * A file of its own so that the backends need not call back up into the seam that calls them. */
#include <gnutls/crypto.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/random.h>

#include "store_backend.h"

int store_piece_name(char name[48])
{
    unsigned char r[16];
    if (getrandom(r, sizeof r, 0) != (ssize_t)sizeof r)
        return SF_EIO;
    int at = snprintf(name, 48, "pieces:");
    for (size_t k = 0; k < sizeof r; k++)
        at += snprintf(name + at, (size_t)(48 - at), "%02x", r[k]);
    return 0;
}

enum job_state store_reaped_state(const struct reaped *r, int max_attempts)
{
    if (r->cancelled)
        return JOB_CANCELLED;
    return r->beside == 0 && r->attempts >= max_attempts ? JOB_FAILED : JOB_QUEUED;
}

void store_rec_free(struct job_rec *r)
{
    if (!r)
        return;
    free(r->request);
    free(r->result);
    free(r->meta);
    free(r->error);
    r->request = r->result = NULL;
    r->meta = r->error = NULL;
}

void store_mesh_free(struct mesh_rec *m)
{
    free(m->type);
    free(m->meta);
    free(m->data);
    memset(m, 0, sizeof *m);
}

void store_volume_free(struct volume_rec *parts, int n)
{
    for (int k = 0; k < n; k++) {
        free((void *)parts[k].format);
        free((void *)parts[k].options);
        free((void *)parts[k].data);
    }
    free(parts);
}

/* One more part for a backend's volume_get (format, options and data copied): 0 or SF_ENOMEM. */
int store_volume_add(struct volume_rec **parts, int *n, int seq, const char *format, const char *options,
                     const void *data, size_t len)
{
    struct volume_rec *p = realloc(*parts, (size_t)(*n + 1) * sizeof *p);
    if (!p)
        return SF_ENOMEM;
    *parts = p;
    char *f = strdup(format), *o = strdup(options), *d = malloc(len ? len : 1);
    if (!f || !o || !d) {
        free(f), free(o), free(d);
        return SF_ENOMEM;
    }
    memcpy(d, data, len);
    p[(*n)++] = (struct volume_rec){seq, f, o, d, len};
    return 0;
}

void store_checksum(const void *a, size_t na, const void *b, size_t nb, char out[65])
{
    unsigned char d[32] = {0};
    gnutls_hash_hd_t h;
    if (gnutls_hash_init(&h, GNUTLS_DIG_SHA256) == 0) {
        gnutls_hash(h, a, na);
        gnutls_hash(h, b, nb);
        gnutls_hash_deinit(h, d);
    }
    for (int k = 0; k < 32; k++)
        snprintf(out + 2 * k, 3, "%02x", d[k]);
}

int store_one_row(int n, int none) { return n < 0 ? SF_EIO : n == 0 ? none : 0; }
