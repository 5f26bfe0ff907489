/* clock.h - the one clock for timings (a stage's milliseconds in --stats and results): monotonic,
 * from an arbitrary start. Not for dates (wall time is the daemon's). */
#ifndef SURFD_CLOCK_H
#define SURFD_CLOCK_H

/* Milliseconds of CLOCK_MONOTONIC. */
double sf_now_ms(void);

#endif
