/* replay.c - runs a fuzz target over files without libFuzzer (make test builds every target with
 * gcc and the sanitizers and this main): each argument is a file or a folder of them. Prints
 * "N inputs" and exits 0; a sanitizer report or an abort fails the run.
 *
 * Built with -DTORTURE (and the daemon's allocator wrappers, daemon/memwrap.c), it is curl's
 * torture test: each input runs once to count its allocations, then again with its first
 * allocation refused, then its second, ... (at most TORTURE_RUNS runs an input, spread evenly over
 * them), and every run must end cleanly and give back every byte it took; a run that does not is
 * printed and the exit status is 1. */
#include <dirent.h>
#include <stdio.h>
#include <sys/stat.h>

#include "fuzz.h"

#define REPLAY_MAX_INPUT (64u << 20) /* bytes of one input at most (max-body's default) */

static long n_inputs;

#ifdef TORTURE
#include <limits.h>

#include "../../core/base/mem.h"

#define TORTURE_RUNS 2000

static long n_runs, n_kept;

static void run_input(const char *path, const uint8_t *buf, size_t size)
{
    struct mem_account whole = {.fail_at = LLONG_MAX}; /* counted, none refused */
    mem_account_enter(&whole);
    LLVMFuzzerTestOneInput(buf, size);
    mem_account_enter(NULL);
    long long n = atomic_load(&whole.allocs), step = n > TORTURE_RUNS ? n / TORTURE_RUNS : 1;
    for (long long k = 1; k <= n; k += step, n_runs++) {
        struct mem_account a = {.fail_at = k};
        mem_account_enter(&a);
        LLVMFuzzerTestOneInput(buf, size);
        mem_account_enter(NULL);
        if (atomic_load(&a.held)) {
            printf("%s: with allocation %lld of %lld refused, %lld bytes were not given back\n", path, k, n,
                   (long long)atomic_load(&a.held));
            n_kept++;
        }
    }
}
#else
static void run_input(const char *path, const uint8_t *buf, size_t size)
{
    (void)path;
    LLVMFuzzerTestOneInput(buf, size);
}
#endif

static void run_file(const char *path, off_t size)
{
    if (size < 0 || size > (off_t)REPLAY_MAX_INPUT)
        return;
    FILE *f = fopen(path, "rb");
    if (!f)
        return;
    uint8_t *buf = malloc(size ? (size_t)size : 1); /* the input's own size: ASan sees a read past its end */
    if (buf && fread(buf, 1, (size_t)size, f) == (size_t)size) {
        run_input(path, buf, (size_t)size);
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
#ifdef TORTURE
    printf("%ld inputs, %ld runs, %ld of them kept bytes\n", n_inputs, n_runs, n_kept);
    return n_kept != 0;
#else
    printf("%ld inputs\n", n_inputs);
    return 0;
#endif
}
