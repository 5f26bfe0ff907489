/* util.c - fuzz_file() for the targets that read a path (config, token files): one file per
 * process under TMPDIR, rewritten for every input. */
#include <stdio.h>
#include <sys/stat.h>
#include <unistd.h>

#include "fuzz.h"

char *fuzz_file(const uint8_t *data, size_t size, unsigned mode)
{
    static char path[256];
    if (!path[0]) {
        const char *dir = getenv("TMPDIR");
        snprintf(path, sizeof path, "%s/surfd-fuzz-%ld", dir && *dir ? dir : "/tmp", (long)getpid());
    }
    FILE *f = fopen(path, "wb");
    if (!f)
        return NULL;
    size_t n = fwrite(data, 1, size, f);
    fclose(f);
    if (n != size || chmod(path, mode))
        return NULL;
    return path;
}
