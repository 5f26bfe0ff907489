/* service.c - small helpers every part of the daemon uses. */
#include "service.h"

#include <fcntl.h>
#include <stdio.h>
#include <sys/random.h>
#include <time.h>

double wall_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_REALTIME, &ts);
    return ts.tv_sec + ts.tv_nsec / 1e9;
}

void service_new_id(char out[40])
{
    unsigned char b[16] = {0};
    if (getrandom(b, sizeof b, 0) != (ssize_t)sizeof b) { /* never on Linux >= 3.17; still unique enough */
        struct timespec ts;
        clock_gettime(CLOCK_REALTIME, &ts);
        for (size_t k = 0; k < sizeof b; k++)
            b[k] ^= (unsigned char)((ts.tv_nsec >> (k % 4 * 8)) + k * 131);
    }
    for (size_t k = 0; k < sizeof b; k++)
        snprintf(out + 2 * k, 3, "%02x", b[k]);
}
