/* kept.c - marching cubes kept for local rebuilds and iso changes (kept.h), and the changes kept
 * extractions report. */
#include "kept.h"

#include <stdlib.h>

void iso_change_free(struct iso_change *c)
{
    free(c->removed);
    free(c->added);
    free(c->corners);
    *c = (struct iso_change){.next_id = c->next_id};
}
