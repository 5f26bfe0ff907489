/* job_state.c - the names of job states (job_state.h). */
#include "job_state.h"

#include <string.h>

static const char *const NAMES[] = {
#define JOB_STATE_NAME(e, name) name,
    JOB_STATES(JOB_STATE_NAME)
#undef JOB_STATE_NAME
};

const char *job_state_name(enum job_state s)
{
    return (unsigned)s < JOB_N_STATES ? NAMES[s] : "unknown";
}

bool job_state_parse(const char *name, enum job_state *out)
{
    for (int k = 0; k < JOB_N_STATES; k++)
        if (!strcmp(NAMES[k], name)) {
            *out = (enum job_state)k;
            return true;
        }
    return false;
}
