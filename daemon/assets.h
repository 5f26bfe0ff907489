/* assets.h - the web page's files (client/web/), compiled into the daemon by the Makefile
 * ($(B)/gen/web.c) and served at their paths: "/" is index.html. */
#ifndef SURFD_ASSETS_H
#define SURFD_ASSETS_H

#include <stddef.h>

struct asset {
    const char *path;   /* "/", "/app.js", ... */
    const char *type;   /* Content-Type */
    const char *data;
    size_t len;
};

extern const struct asset surfd_assets[]; /* ends with a NULL path */

#endif
