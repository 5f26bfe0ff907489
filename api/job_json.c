/* job_json.c - job resources with jansson. */
#include "job_json.h"

#include <jansson.h>
#include <math.h>
#include <stdlib.h>
#include <stdio.h>
#include <time.h>

json_t *job_stamp(double t)
{
    if (!(t > 0))
        return json_null();
    time_t s = (time_t)t;
    struct tm tm;
    gmtime_r(&s, &tm);
    char buf[40], out[48];
    strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%S", &tm);
    snprintf(out, sizeof out, "%s.%03dZ", buf, (int)((t - (double)s) * 1000));
    return json_string(out);
}

static json_t *job_object(const struct job_view *v)
{
    char self[80], result[96];
    snprintf(self, sizeof self, "/jobs/%s", v->id);
    snprintf(result, sizeof result, "/jobs/%s/result", v->id);
    json_t *err = v->error ? json_loads(v->error, 0, NULL) : NULL;
    return json_pack("{s:s, s:s, s:s, s:f, s:o, s:o, s:o, s:o, s:i, s:o, s:{s:s, s:s}}", "id", v->id, "kind", v->kind,
                     "state", v->state, "progress", round(v->progress * 1000) / 1000, "created", job_stamp(v->created),
                     "started", job_stamp(v->started), "finished", job_stamp(v->finished), "error", err ? err : json_null(),
                     "attempts", v->attempts, "node", v->node && *v->node ? json_string(v->node) : json_null(),
                     "links", "self", self, "result", result);
}

char *job_json(const struct job_view *v)
{
    json_t *o = job_object(v);
    char *s = o ? json_dumps(o, JSON_COMPACT) : NULL;
    json_decref(o);
    return s;
}

char *job_list_json(const struct job_view *v, int n)
{
    json_t *a = json_array();
    for (int k = 0; k < n; k++)
        json_array_append_new(a, job_object(&v[k]));
    json_t *o = json_pack("{s:o}", "jobs", a);
    char *s = o ? json_dumps(o, JSON_COMPACT) : NULL;
    json_decref(o);
    return s;
}
