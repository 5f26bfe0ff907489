/* Reading a JSON request body with a bound on the memory its tree takes (json_in.h). */
#include "json_in.h"

#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

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

/* Parses text[0 .. len) with the values bound `most`. The text is the body's from byte `at` on (an
 * element: any value), or the body with its bytes [gap, gap + gap_len) left out (the rest of a
 * split document): errors say where in the body, counted to the last byte jansson read (as its
 * column does; an empty element reads what ends it). */
static int parse(const char *text, size_t len, size_t most, const char *body, size_t at, size_t gap, size_t gap_len,
                 json_t **root, struct sf_err *err)
{
    *root = NULL;
    if (values_at_most(text, len) > most)
        return sf_fail(err, SF_ELIMIT, "", "the body holds over %zu JSON values", most);
    json_error_t je;
    if (!(*root = json_loadb(text, len, JSON_REJECT_DUPLICATES | (at ? JSON_DECODE_ANY : 0), &je))) {
        int line = je.line, column = je.column;
        if (at || gap_len) { /* (jansson counted in the text: count again in the body) */
            size_t end = je.position > 0 ? (size_t)je.position : 1;
            end = at + (end > gap ? end + gap_len : end);
            line = 1, column = 0;
            for (size_t i = 0; i < end; i++)
                line += body[i] == '\n', column = body[i] == '\n' ? 0 : column + 1;
        }
        char where[64];
        snprintf(where, sizeof where, "line %d, column %d", line, column);
        return sf_fail(err, SF_EFORMAT, where, "not JSON: %s", je.text);
    }
    return 0;
}

int json_read(const char *buf, size_t len, json_t **root, struct sf_err *err)
{
    return parse(buf, len, JSON_MAX_VALUES, buf, 0, 0, 0, root, err);
}

/* ---- one array held back ----
 * A scan of the structure alone (strings, brackets, commas): what it cannot walk is left to
 * jansson's whole parse, which says what is wrong. */

static size_t skip_space(const char *b, size_t len, size_t i)
{
    while (i < len && (b[i] == ' ' || b[i] == '\t' || b[i] == '\n' || b[i] == '\r'))
        i++;
    return i;
}

/* Past the string opening at b[i] ('"'); len when it does not close. */
static size_t skip_string(const char *b, size_t len, size_t i)
{
    for (i++; i < len; i++)
        if (b[i] == '\\')
            i++;
        else if (b[i] == '"')
            return i + 1;
    return len;
}

/* Past the value starting at b[i] (to the ',', '}' or ']' that ends it at its depth); len when
 * the brackets do not balance. */
static size_t skip_value(const char *b, size_t len, size_t i)
{
    int depth = 0;
    for (; i < len; i++) {
        char c = b[i];
        if (c == '"')
            i = skip_string(b, len, i) - 1;
        else if (c == '[' || c == '{')
            depth++;
        else if ((c == ']' || c == '}') && depth-- == 0)
            return i;
        else if (c == ',' && depth == 0)
            return i;
    }
    return depth == 0 ? len : len + 1;
}

/* Finds member key of the top-level object: its value from b[*at] to the ',' or '}' at *end. */
static bool find_member(const char *b, size_t len, const char *key, size_t *at, size_t *end)
{
    size_t i = skip_space(b, len, 0), klen = strlen(key);
    if (i >= len || b[i] != '{')
        return false;
    for (i = skip_space(b, len, i + 1); i < len && b[i] == '"';) {
        size_t k0 = i + 1, k1 = skip_string(b, len, i);
        i = skip_space(b, len, k1);
        if (i >= len || b[i] != ':')
            return false;
        i = skip_space(b, len, i + 1);
        size_t e = skip_value(b, len, i);
        if (e >= len)
            return false;
        if (k1 - 1 - k0 == klen && !memcmp(b + k0, key, klen)) {
            *at = i, *end = e;
            return true;
        }
        if (b[e] != ',')
            return false;
        i = skip_space(b, len, e + 1);
    }
    return false;
}

bool json_has_member(const char *b, size_t len, const char *key)
{
    size_t at, end;
    return find_member(b, len, key, &at, &end);
}

/* Finds key's array in the top-level object: its '[' at *open and the matching ']' at *close. */
static bool find_array(const char *b, size_t len, const char *key, size_t *open, size_t *close)
{
    size_t i, end;
    if (!find_member(b, len, key, &i, &end) || b[i] != '[')
        return false;
    size_t j = end; /* back from the value's end over space to its ']' */
    while (j > i && (b[j - 1] == ' ' || b[j - 1] == '\t' || b[j - 1] == '\n' || b[j - 1] == '\r'))
        j--;
    if (j <= i || b[j - 1] != ']')
        return false;
    *open = i, *close = j - 1;
    return true;
}

int json_read_split(const char *buf, size_t len, const char *const *keys, size_t max_elements, json_t **root,
                    struct json_split *sp, struct sf_err *err)
{
    memset(sp, 0, sizeof *sp);
    sp->buf = buf;
    size_t open = 0, close = 0, values = values_at_most(buf, len), cap = 0;
    while (*keys && !find_array(buf, len, *keys, &open, &close))
        keys++;
    if (!*keys)
        return json_read(buf, len, root, err);
    sp->key = *keys;
    if (values > JSON_MAX_SPLIT_VALUES)
        return sf_fail(err, SF_ELIMIT, "", "the body holds over %d JSON values", JSON_MAX_SPLIT_VALUES);
    for (size_t i = skip_space(buf, close, open + 1); i < close && sp->n <= max_elements;) { /* the elements' ranges */
        size_t end = skip_value(buf, close, i), next = end < close ? skip_space(buf, close, end + 1) : close;
        if (end > close || (end < close && (buf[end] != ',' || next == close))) { /* (a trailing comma too) */
            json_split_free(sp);
            return json_read(buf, len, root, err); /* not walkable: jansson's answer */
        }
        if (sp->n == cap) {
            size_t (*r)[2] = realloc(sp->range, sizeof *r * (cap = cap ? 2 * cap : 1024));
            if (!r) {
                json_split_free(sp);
                return sf_fail(err, SF_ENOMEM, "", "out of memory");
            }
            sp->range = r;
        }
        sp->range[sp->n][0] = i, sp->range[sp->n][1] = end;
        sp->n++;
        i = next;
    }
    char *rest = malloc(len - (close - open - 1));
    if (!rest) {
        json_split_free(sp);
        return sf_fail(err, SF_ENOMEM, "", "out of memory");
    }
    memcpy(rest, buf, open + 1);
    memcpy(rest + open + 1, buf + close, len - close);
    int rc = parse(rest, len - (close - open - 1), JSON_MAX_VALUES, buf, 0, open + 1, close - open - 1, root, err);
    free(rest);
    if (rc)
        json_split_free(sp);
    else
        sp->held = true;
    return rc;
}

int json_read_element(const struct json_split *sp, size_t k, json_t **out, struct sf_err *err)
{
    const size_t *r = sp->range[k];
    return parse(sp->buf + r[0], r[1] - r[0], JSON_MAX_VALUES, sp->buf, r[0], 0, 0, out, err);
}

void json_split_free(struct json_split *sp)
{
    free(sp->range);
    memset(sp, 0, sizeof *sp);
}
