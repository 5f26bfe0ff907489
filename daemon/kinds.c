/* kinds.c - the kinds by name, for the jobs the store hands back, and the one start (kinds.h). */
#include "kinds.h"

#include <stdlib.h>
#include <string.h>

static const struct job_kind *const KINDS[] = {&render_kind, &volume_kind,     &model_kind,  &mesh_kind, &patches_kind,
                                               &rtstruct_kind, &isosurface_kind, &matrix_kind, &edit_kind,
                                               &pull_kind,     &send_kind};

const struct job_kind *job_kind(const char *name)
{
    for (size_t k = 0; k < sizeof KINDS / sizeof *KINDS; k++)
        if (!strcmp(KINDS[k]->name, name))
            return KINDS[k];
    return NULL;
}

int job_start(struct service *svc, const struct job_claim *c)
{
    const struct job_kind *kind = job_kind(c->kind);
    if (!kind)
        return SF_ENOTFOUND;
    struct job_work *w = calloc(1, kind->work_size);
    if (!w)
        return SF_ENOMEM;
    w->svc = svc;
    w->claim = *c;
    if (jobq_submit(svc->q, c->id, kind->ops, w, true)) {
        free(w);
        return SF_ELIMIT;
    }
    return 0;
}
