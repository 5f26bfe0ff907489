/* log.h - one log for the daemon: lines "time level message" on stderr (journald adds its own
 * metadata). LOG() checks the level before formatting anything. Never log tokens or request
 * bodies (patient data); the access log takes method, path without query, status, bytes, ms. */
#ifndef SURFD_LOG_H
#define SURFD_LOG_H

enum log_level { LOG_ERROR, LOG_WARN, LOG_INFO, LOG_DEBUG };

extern enum log_level log_threshold;

int log_set_level(const char *name);
void log_write(enum log_level level, const char *fmt, ...) __attribute__((format(printf, 2, 3)));

#define LOG(level, ...)                          \
    do {                                         \
        if ((level) <= log_threshold)            \
            log_write((level), __VA_ARGS__);     \
    } while (0)

#endif
