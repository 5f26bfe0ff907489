/* fuzz.h - what every fuzz target shares: libFuzzer's entry point, and a copy of the input as a
 * NUL-terminated string (the decoders take a length, but the text ones must not read past it
 * even so: the copy's terminator sits one past, where ASan would see an overrun of the original). */
#ifndef SURFD_FUZZ_H
#define SURFD_FUZZ_H

#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "../../api/scene_io.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static inline char *fuzz_text(const uint8_t *data, size_t size)
{
    char *t = malloc(size + 1);
    if (t) {
        memcpy(t, data, size);
        t[size] = 0;
    }
    return t;
}

/* Splits a copy of the input as a request: its first line the query (NUL-terminated in place),
 * the rest the body (*body, *len). The copy, to free; NULL when out of memory. */
static inline char *fuzz_request(const uint8_t *data, size_t size, const char **body, size_t *len)
{
    char *text = fuzz_text(data, size);
    if (!text)
        return NULL;
    char *nl = memchr(text, '\n', size);
    *body = nl ? nl + 1 : "";
    *len = nl ? size - (size_t)(nl + 1 - text) : 0;
    if (nl)
        *nl = 0;
    return text;
}

/* Runs a text scene decoder (.bpt, VRML) over the input as a string, then validates the scene
 * and extracts its patches, as a render job does. */
static inline void fuzz_text_scene(const uint8_t *data, size_t size,
                                   int (*parse)(const char *, size_t, struct scene *, struct sf_err *))
{
    struct scene sc;
    struct sf_err err = {0};
    char *text = fuzz_text(data, size);
    if (text && parse(text, size, &sc, &err) == 0) {
        struct patch_set ps;
        if (scene_patches(&sc, &ps, &err) == 0)
            nurbs_patch_set_free(&ps);
        scene_free(&sc);
    }
    free(text);
}

/* The input as a file of its own (for decoders that read paths): the path, or NULL. mode as chmod. */
char *fuzz_file(const uint8_t *data, size_t size, unsigned mode);

#endif
