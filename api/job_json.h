/* job_json.h - the job resource of API.md: {id, kind, state, progress, created, started,
 * finished, error, attempts, node, links}. Times are Unix seconds in, RFC 3339 UTC out (null when 0). */
#ifndef SURFD_JOB_JSON_H
#define SURFD_JOB_JSON_H

#include <jansson.h>

struct job_view {
    const char *id, *kind, *state;
    double progress;
    double created, started, finished;
    const char *error;   /* problem JSON text, or NULL */
    int attempts;        /* times a node has started it */
    const char *node;    /* the node that runs it or ran it last ("": none yet) */
};

/* Caller frees. */
char *job_json(const struct job_view *v);
/* A time (Unix seconds) as RFC 3339 UTC with milliseconds ("2026-12-06T01:59:18.457Z"), what every
 * resource's times say: a JSON string, null for 0 (never). */
json_t *job_stamp(double t);
/* {"jobs": [...]} from n views. Caller frees. */
char *job_list_json(const struct job_view *v, int n);

#endif
