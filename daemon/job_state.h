/* job_state.h - the states of a job and their names (the one table of them): the store, the
 * queue, the HTTP layer and /metrics all speak this enum; only job_state_name() makes text. */
#ifndef SURFD_JOB_STATE_H
#define SURFD_JOB_STATE_H

#include <stdbool.h>

#define JOB_STATES(X)                 \
    X(JOB_QUEUED, "queued")           \
    X(JOB_RUNNING, "running")         \
    X(JOB_SUCCEEDED, "succeeded")     \
    X(JOB_FAILED, "failed")           \
    X(JOB_CANCELLED, "cancelled")

enum job_state {
#define JOB_STATE_ENUM(e, name) e,
    JOB_STATES(JOB_STATE_ENUM)
#undef JOB_STATE_ENUM
    JOB_N_STATES
};

/* "queued", ...; "unknown" out of range. */
const char *job_state_name(enum job_state s);
/* false when name is none of them. */
bool job_state_parse(const char *name, enum job_state *out);
/* succeeded, failed or cancelled. */
static inline bool job_state_ended(enum job_state s) { return s >= JOB_SUCCEEDED; }

#endif
