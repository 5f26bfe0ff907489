/* Reading a JSON request body with a bound on the memory its tree takes (json_in.h). */
#include "json_in.h"

#include <stdbool.h>
#include <stdio.h>

/* An upper bound on the number of values in buf: every value but a document's first follows a
 * ',' or opens a container, so values <= commas + brackets + 1 (counted outside strings). */
static size_t values_at_most(const char *buf, size_t len)
{
    size_t n = 1;
    bool in_string = false, escaped = false;
    for (size_t i = 0; i < len; i++) {
        char c = buf[i];
        if (in_string) {
            if (escaped)
                escaped = false;
            else if (c == '\\')
                escaped = true;
            else if (c == '"')
                in_string = false;
        } else if (c == '"') {
            in_string = true;
        } else if (c == ',' || c == '[' || c == '{') {
            n++;
        }
    }
    return n;
}

int json_read(const char *buf, size_t len, json_t **root, struct sf_err *err)
{
    *root = NULL;
    if (values_at_most(buf, len) > JSON_MAX_VALUES)
        return sf_fail(err, SF_ELIMIT, "", "the body holds over %d JSON values", JSON_MAX_VALUES);
    json_error_t je;
    if (!(*root = json_loadb(buf, len, JSON_REJECT_DUPLICATES, &je))) {
        char where[64];
        snprintf(where, sizeof where, "line %d, column %d", je.line, je.column);
        return sf_fail(err, SF_EFORMAT, where, "not JSON: %s", je.text);
    }
    return 0;
}
