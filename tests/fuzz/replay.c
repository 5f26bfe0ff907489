/* replay.c - runs a fuzz target over files without libFuzzer (make test builds every target with
 * gcc and the sanitizers and this main): each argument is a file or a folder of them. Prints
 * "N inputs" and exits 0; a sanitizer report or an abort fails the run. */
#include <dirent.h>
#include <stdio.h>
#include <sys/stat.h>

#include "fuzz.h"

#define REPLAY_MAX_INPUT (64u << 20) /* bytes of one input at most (max-body's default) */

static long n_inputs;

static void run_file(const char *path, off_t size)
{
    if (size < 0 || size > (off_t)REPLAY_MAX_INPUT)
        return;
    FILE *f = fopen(path, "rb");
    if (!f)
        return;
    uint8_t *buf = malloc(size ? (size_t)size : 1); /* the input's own size: ASan sees a read past its end */
    if (buf && fread(buf, 1, (size_t)size, f) == (size_t)size) {
        LLVMFuzzerTestOneInput(buf, (size_t)size);
        n_inputs++;
    }
    free(buf);
    fclose(f);
}

static void run_path(const char *path)
{
    struct stat st;
    if (stat(path, &st))
        return;
    if (!S_ISDIR(st.st_mode)) {
        run_file(path, st.st_size);
        return;
    }
    DIR *d = opendir(path);
    struct dirent *e;
    while (d && (e = readdir(d))) {
        if (e->d_name[0] == '.')
            continue;
        char sub[4096];
        snprintf(sub, sizeof sub, "%s/%s", path, e->d_name);
        run_path(sub);
    }
    if (d)
        closedir(d);
}

int main(int argc, char **argv)
{
    for (int k = 1; k < argc; k++)
        run_path(argv[k]);
    printf("%ld inputs\n", n_inputs);
    return 0;
}
