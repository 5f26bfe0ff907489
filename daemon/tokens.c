/* tokens.c - the token file: reading, checking its mode, parsing its lines (tokens.h). */
#include "tokens.h"

#include <ctype.h>
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

/* One token a line: "name:secret" or "name:secret:admin", or a bare "secret" (named "default");
 * blank lines and # comments skipped. Names are letters, digits, '.', '_' and '-'. A file others
 * may read or write, or its group write, is refused: it holds every client's credentials. */
int tokens_read(const char *path, struct token **tokens, size_t *n_tokens, struct sf_err *err)
{
    FILE *f = fopen(path, "r");
    if (!f)
        return sf_fail(err, SF_EIO, "", "token file %s: %s", path, strerror(errno));
    int rc = SF_EINVAL, n = 0;
    struct stat st;
    if (fstat(fileno(f), &st) == 0 && (st.st_mode & 0027)) {
        sf_fail(err, SF_EINVAL, "", "token file %.200s is mode %04o: others may read it or the group may write it; "
                 "chmod 0600 (or 0640 for a group the service is in)", path, (unsigned)(st.st_mode & 07777));
        goto out_close;
    }
    char line[512];
    while (fgets(line, sizeof line, f)) {
        n++;
        line[strcspn(line, "\r\n")] = 0;
        char *t = line;
        while (*t == ' ' || *t == '\t')
            t++;
        if (!*t || *t == '#')
            continue;
        char *name = "default", *secret = t, *c1 = strchr(t, ':');
        bool admin = false;
        if (c1) {
            *c1 = 0;
            name = t;
            secret = c1 + 1;
            char *c2 = strchr(secret, ':');
            if (c2) {
                *c2 = 0;
                if (!(admin = !strcmp(c2 + 1, "admin"))) {
                    sf_fail(err, SF_EINVAL, "", "token file %.200s:%d: expected name:token or name:token:admin", path,
                            n);
                    goto out_close;
                }
            }
            bool ok = *name && strlen(name) < 64 && *secret;
            for (const char *p = name; *p; p++)
                ok &= isalnum((unsigned char)*p) || *p == '.' || *p == '_' || *p == '-';
            if (!ok) {
                sf_fail(err, SF_EINVAL, "", "token file %.200s:%d: a name is 1-63 letters, digits, '.', '_' or '-', "
                        "then ':' and the token", path, n);
                goto out_close;
            }
        }
        struct token *more = realloc(*tokens, sizeof *more * (*n_tokens + 1));
        if (!more) {
            rc = sf_fail(err, SF_ENOMEM, "", "out of memory");
            goto out_close;
        }
        *tokens = more;
        struct token *tk = &more[*n_tokens];
        *tk = (struct token){strdup(name), strdup(secret), admin};
        if (!tk->name || !tk->secret) {
            free(tk->name);
            free(tk->secret);
            rc = sf_fail(err, SF_ENOMEM, "", "out of memory");
            goto out_close;
        }
        (*n_tokens)++;
    }
    if (*n_tokens == 0)
        sf_fail(err, SF_EINVAL, "", "token file %s holds no token", path);
    else
        rc = 0;
out_close:
    fclose(f);
    return rc;
}

void tokens_free(struct token *tokens, size_t n_tokens)
{
    for (size_t k = 0; k < n_tokens; k++) {
        free(tokens[k].name);
        free(tokens[k].secret);
    }
    free(tokens);
}
