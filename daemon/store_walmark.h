/* store_walmark.h - how the embedded store finds commits lost from its WAL.
 *
 * SQLite reads a WAL up to its first frame that fails its checksum and takes everything after as
 * never written: a WAL truncated or damaged behind its back loses the commits there silently (the
 * store starts as if they had not been made). A crash does not: with synchronous=NORMAL a killed
 * process loses no commit, since the kernel keeps what it wrote; only a power cut may lose the
 * last ones. So after every commit the store notes in DIR/surfd.db-mark how many frames the WAL
 * held (the WAL hook), with the WAL's salts and the machine's boot id; at the next start, on the
 * same boot, a WAL that holds fewer valid frames than the mark has lost commits. A mark from an
 * earlier boot is not compared (a power cut may have lost the last commits: what NORMAL trades),
 * nor one whose WAL was restarted (new salts: its frames were all in the database first).
 *
 * The mark is written with pwrite and no fsync (a few microseconds a commit). The process that
 * serves the store holds it locked; another (surfd store check while the service runs) leaves it
 * alone. A loss found is kept in the mark until `surfd store recover` accepts it. */
#ifndef SURFD_STORE_WALMARK_H
#define SURFD_STORE_WALMARK_H

#include <sqlite3.h>
#include <stddef.h>

struct walmark;

/* Takes the mark of the database at db_path (db_path-mark) for this process, after db was opened
 * and before anything is written to it; compares the WAL with the mark, keeps the commits noted
 * from now on (the hook, which also checkpoints every 1000 frames as SQLite's own does). NULL when
 * another process holds the mark, or it cannot be made. */
struct walmark *walmark_open(const char *db_path, sqlite3 *db);
/* The loss found (a sentence), or NULL. */
const char *walmark_finding(const struct walmark *wm);
/* Accepts the store as it is: the loss forgotten, the WAL's frames noted from now on. 0 or -1. */
int walmark_accept(struct walmark *wm);
/* Before the database is closed (its WAL checkpointed and removed): notes a clean close. */
void walmark_closing(struct walmark *wm);
void walmark_free(struct walmark *wm);

#endif
