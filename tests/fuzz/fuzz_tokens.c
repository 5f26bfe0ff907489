/* fuzz_tokens.c - token files: the input as a 0600 file through tokens_read. */
#include "../../daemon/tokens.h"
#include "fuzz.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    char *path = fuzz_file(data, size, 0600);
    struct sf_err err = {0};
    struct token *t = NULL;
    size_t n = 0;
    if (path)
        tokens_read(path, &t, &n, &err);
    tokens_free(t, n);
    return 0;
}
