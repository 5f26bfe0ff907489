/* log.c - the daemon's log writer: one fprintf per line, so lines from threads never interleave. */
#include "log.h"

#include <stdarg.h>
#include <stdio.h>
#include <string.h>
#include <time.h>

enum log_level log_threshold = LOG_INFO;

static const char *const NAMES[] = {"error", "warn", "info", "debug"};

int log_set_level(const char *name)
{
    for (int k = 0; k < 4; k++)
        if (!strcmp(name, NAMES[k])) {
            log_threshold = (enum log_level)k;
            return 0;
        }
    return -1;
}

void log_write(enum log_level level, const char *fmt, ...)
{
    char msg[1024], stamp[32];
    struct timespec ts;
    struct tm tm;
    clock_gettime(CLOCK_REALTIME, &ts);
    gmtime_r(&ts.tv_sec, &tm);
    strftime(stamp, sizeof stamp, "%Y-%m-%dT%H:%M:%S", &tm);
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    fprintf(stderr, "%s.%03ldZ %s %s\n", stamp, ts.tv_nsec / 1000000, NAMES[level], msg);
}
