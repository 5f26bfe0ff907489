/* tokens.h - bearer tokens from the token file: one a line, "name:secret" or "name:secret:admin",
 * or a bare "secret" (named "default"); blank lines and # comments skipped. Jobs and models belong
 * to the name that made them; other names get 404; admins see all. */
#ifndef SURFD_TOKENS_H
#define SURFD_TOKENS_H

#include <stdbool.h>
#include <stddef.h>

#include "../core/base/err.h"

struct token {
    char *name;
    char *secret;
    bool admin;
};

/* Appends the file's tokens to *tokens (growing it; *n_tokens counts them). A file others may read,
 * or its group write, is refused, as is a malformed line (err names the line) or a file without a
 * token: SF_EINVAL, or SF_EIO (the file) or SF_ENOMEM, with err's message. What was read stays in
 * *tokens either way: the caller frees it with tokens_free(). */
int tokens_read(const char *path, struct token **tokens, size_t *n_tokens, struct sf_err *err);
void tokens_free(struct token *tokens, size_t n_tokens);

#endif
