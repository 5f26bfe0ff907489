/* image.c - loads libsurfd-image.so (the OpenImageIO shim, image_oiio.cpp) on first use; see
 * image.h for why it is not linked. One pthread_once: every thread that asks waits for the
 * one load and sees its outcome. */
#include "image.h"
#include "png.h"

#include <dlfcn.h>
#include <limits.h>
#include <pthread.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

#define IMAGE_LIB "libsurfd-image.so"

static pthread_once_t load_once = PTHREAD_ONCE_INIT;
static __typeof__(image_oiio_encode) *encode_fn;
static char load_error[PATH_MAX + 256];

/* the candidates, in order: next to the executable, then ../lib/surfd/ beside its bin/ */
static int candidate(int k, char *path, size_t cap)
{
    char exe[PATH_MAX];
    ssize_t n = readlink("/proc/self/exe", exe, sizeof exe - 1);
    if (n <= 0)
        return -1;
    exe[n] = '\0';
    char *slash = strrchr(exe, '/');
    if (!slash)
        return -1;
    *slash = '\0';
    const char *rel[] = {"/" IMAGE_LIB, "/../lib/surfd/" IMAGE_LIB};
    if (k >= (int)(sizeof rel / sizeof rel[0]))
        return -1;
    return snprintf(path, cap, "%s%s", exe, rel[k]) < (int)cap ? 0 : -1;
}

static int locate(char *path, size_t cap)
{
    for (int k = 0; candidate(k, path, cap) == 0; k++)
        if (access(path, R_OK) == 0)
            return 0;
    char first[PATH_MAX] = "", second[PATH_MAX] = "";
    candidate(0, first, sizeof first);
    candidate(1, second, sizeof second);
    snprintf(load_error, sizeof load_error, "the image writers (%s) are in neither %s nor %s", IMAGE_LIB, first,
             second);
    return -1;
}

static void load(void)
{
    char path[PATH_MAX];
    if (locate(path, sizeof path))
        return;
    void *lib = dlopen(path, RTLD_NOW | RTLD_LOCAL); /* kept for the process's life */
    __typeof__(image_oiio_init) *init_fn = NULL;
    if (lib) { /* POSIX's way of turning dlsym()'s object pointer into a function pointer */
        *(void **)&init_fn = dlsym(lib, "image_oiio_init");
        *(void **)&encode_fn = dlsym(lib, "image_oiio_encode");
    }
    if (!init_fn || !encode_fn) {
        snprintf(load_error, sizeof load_error, "cannot load the image writers: %s", dlerror());
        encode_fn = NULL;
        return;
    }
    init_fn();
}

int image_locate(struct sf_err *err)
{
    char path[PATH_MAX];
    if (locate(path, sizeof path))
        return sf_fail(err, SF_EBACKEND, "", "%s", load_error);
    return 0;
}

int image_init(struct sf_err *err)
{
    pthread_once(&load_once, load);
    if (!encode_fn)
        return sf_fail(err, SF_EBACKEND, "", "%s", load_error);
    return 0;
}

int image_encode(const struct frame_image *img, enum image_format fmt, unsigned char **out, size_t *out_len,
                 struct sf_err *err)
{
    *out = NULL;
    *out_len = 0;
    if (fmt == IMG_PNG && img->srgb8) /* by hand, without the library (png.h) */
        return png_encode(img->srgb8, img->width, img->height, out, out_len, err);
    int rc = image_init(err);
    return rc ? rc : encode_fn(img, fmt, out, out_len, err);
}
