/* job_edit.h - the extractions the edit kind keeps in memory (job_edit.c), given or built for the
 * isosurface kind when it makes one. */
#ifndef SURFD_JOB_EDIT_H
#define SURFD_JOB_EDIT_H

#include "volumes.h"

/* An isosurface job's kept hierarchy a (iso_adapt_keep; NULL: none) for the model's edits, with
 * its volume's settings (not its samples); a is taken (freed when it does not fit edit-memory). */
void edit_keep(struct service *svc, const char *id, const struct volume *vol, struct iso_adapt *a);
/* Model id's extraction built from the store and kept for its edits (marching cubes kept: levels
 * 1), unless it is kept already; an isosurface job calls it after its answer. */
void edit_warm(struct service *svc, const char *id);
/* Stops the thread that measures edited models whole once their edits rest (after the pool). */
void edit_stop(void);

#endif
