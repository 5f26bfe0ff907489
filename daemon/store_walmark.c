/* store_walmark.c - the WAL mark (store_walmark.h). The WAL's header is read as the file format
 * page gives it (https://www.sqlite.org/fileformat2.html#walformat): magic 0x377f0682 or 0x377f0683
 * at 0, salt-1 and salt-2 at 16 and 20. No library reads it: SQLite keeps it to itself. */
#include "store_walmark.h"

#include <fcntl.h>
#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/file.h>
#include <unistd.h>

#define MARK_BYTES 1024       /* the record, written whole at offset 0 */
#define AUTO_CHECKPOINT 1000  /* frames, as SQLite's default hook */

enum mark_state { MARK_OPEN, MARK_CLOSED, MARK_LOST };
static const char *const STATE_NAMES[] = {"open", "closed", "lost"};

struct mark {
    char boot[40];
    unsigned salt1, salt2;
    int frames;               /* in the WAL after the last commit */
    int ckpt;                 /* of them, in the database too (the last checkpoint's) */
    enum mark_state state;
    char finding[480];        /* MARK_LOST: what was lost */
};

struct walmark {
    int fd;                   /* the mark, locked */
    char wal[1100];
    sqlite3 *db;
    struct mark m;            /* as last written */
};

static void boot_id(char out[40])
{
    FILE *f = fopen("/proc/sys/kernel/random/boot_id", "r");
    if (!f || !fgets(out, 40, f))
        snprintf(out, 40, "unknown");
    out[strcspn(out, "\n")] = 0;
    if (f)
        fclose(f);
}

/* The WAL's salts: true, or false when it has no valid header (absent, short, or not a WAL). */
static bool wal_salts(const char *wal, unsigned *salt1, unsigned *salt2)
{
    unsigned char h[32];
    int fd = open(wal, O_RDONLY | O_CLOEXEC);
    bool ok = fd >= 0 && pread(fd, h, sizeof h, 0) == (ssize_t)sizeof h && h[0] == 0x37 && h[1] == 0x7f &&
              h[2] == 0x06 && (h[3] == 0x82 || h[3] == 0x83);
    if (fd >= 0)
        close(fd);
    if (ok) {
        *salt1 = (unsigned)h[16] << 24 | (unsigned)h[17] << 16 | (unsigned)h[18] << 8 | h[19];
        *salt2 = (unsigned)h[20] << 24 | (unsigned)h[21] << 16 | (unsigned)h[22] << 8 | h[23];
    }
    return ok;
}

static void put(struct walmark *wm)
{
    char rec[MARK_BYTES];
    int n = snprintf(rec, sizeof rec, "surfd-wal-mark 1 boot=%s salts=%08x%08x frames=%d ckpt=%d state=%s\n%s\n",
                     wm->m.boot, wm->m.salt1, wm->m.salt2, wm->m.frames, wm->m.ckpt, STATE_NAMES[wm->m.state],
                     wm->m.state == MARK_LOST ? wm->m.finding : "");
    n = n < 0 ? 0 : n >= (int)sizeof rec ? (int)sizeof rec - 1 : n;
    memset(rec + n, ' ', sizeof rec - (size_t)n - 1);
    rec[sizeof rec - 1] = '\n';
    if (pwrite(wm->fd, rec, sizeof rec, 0) != (ssize_t)sizeof rec) {
        /* nothing to do: the mark only ever under-states, and the next commit writes it again */
    }
}

static bool get(int fd, struct mark *m)
{
    char rec[MARK_BYTES + 1], state[16];
    ssize_t n = pread(fd, rec, MARK_BYTES, 0);
    if (n <= 0)
        return false;
    rec[n] = 0;
    memset(m, 0, sizeof *m);
    if (sscanf(rec, "surfd-wal-mark 1 boot=%39s salts=%8x%8x frames=%d ckpt=%d state=%15s", m->boot, &m->salt1,
               &m->salt2, &m->frames, &m->ckpt, state) != 6)
        return false;
    for (int k = 0; k < 3; k++)
        if (!strcmp(state, STATE_NAMES[k]))
            m->state = (enum mark_state)k;
    char *line = strchr(rec, '\n');
    if (line) {
        snprintf(m->finding, sizeof m->finding, "%s", line + 1);
        m->finding[strcspn(m->finding, "\n")] = 0;
    }
    return true;
}

static int hook(void *arg, sqlite3 *db, const char *name, int frames)
{
    struct walmark *wm = arg;
    unsigned salt1 = 0, salt2 = 0;
    wal_salts(wm->wal, &salt1, &salt2);
    if (salt1 != wm->m.salt1 || salt2 != wm->m.salt2) /* the WAL restarted: nothing of it checkpointed */
        wm->m.salt1 = salt1, wm->m.salt2 = salt2, wm->m.ckpt = 0;
    wm->m.frames = frames;
    if (frames >= AUTO_CHECKPOINT) {
        int log = 0, ckpt = 0;
        if (sqlite3_wal_checkpoint_v2(db, name, SQLITE_CHECKPOINT_PASSIVE, &log, &ckpt) == SQLITE_OK && ckpt > 0)
            wm->m.ckpt = ckpt;
    }
    put(wm);
    return SQLITE_OK;
}

/* Notes the WAL as it is now and keeps noting it. */
static void start(struct walmark *wm, int frames, int ckpt)
{
    wm->m.state = MARK_OPEN;
    wm->m.frames = frames > 0 ? frames : 0;
    wm->m.ckpt = ckpt > 0 ? ckpt : 0;
    wm->m.salt1 = wm->m.salt2 = 0;
    wal_salts(wm->wal, &wm->m.salt1, &wm->m.salt2);
    put(wm);
    sqlite3_wal_hook(wm->db, hook, wm);
}

struct walmark *walmark_open(const char *db_path, sqlite3 *db)
{
    char path[1100];
    snprintf(path, sizeof path, "%s-mark", db_path);
    struct walmark *wm = calloc(1, sizeof *wm);
    if (!wm)
        return NULL;
    wm->db = db;
    snprintf(wm->wal, sizeof wm->wal, "%s-wal", db_path);
    if ((wm->fd = open(path, O_RDWR | O_CREAT | O_CLOEXEC, 0600)) < 0 || flock(wm->fd, LOCK_EX | LOCK_NB)) {
        walmark_free(wm);
        return NULL;
    }
    struct mark old = {0};
    bool had = get(wm->fd, &old);
    unsigned salt1 = 0, salt2 = 0;
    bool header = wal_salts(wm->wal, &salt1, &salt2); /* before the checkpoint below can restart it */
    int log = -1, ckpt = -1; /* the WAL's valid frames, as SQLite reads them (a read opens it first) */
    sqlite3_exec(db, "SELECT count(*) FROM sqlite_master", NULL, NULL, NULL);
    sqlite3_wal_checkpoint_v2(db, NULL, SQLITE_CHECKPOINT_PASSIVE, &log, &ckpt);
    boot_id(wm->m.boot);
    if (had && old.state == MARK_LOST) {
        wm->m = old;
        return wm;
    }
    int kept = log > old.ckpt ? log : old.ckpt; /* frames whose commits the database still has */
    bool lost = had && !strcmp(old.boot, wm->m.boot) &&
                (header ? salt1 == old.salt1 && salt2 == old.salt2 && old.frames > kept
                        : old.state != MARK_CLOSED && old.frames > old.ckpt);
    if (lost) {
        wm->m.state = MARK_LOST;
        wm->m.salt1 = old.salt1, wm->m.salt2 = old.salt2;
        wm->m.frames = old.frames, wm->m.ckpt = old.ckpt;
        const char *name = strrchr(wm->wal, '/') ? strrchr(wm->wal, '/') + 1 : wm->wal;
        snprintf(wm->m.finding, sizeof wm->m.finding,
                 "the WAL (%.64s) %s %d valid frames of the %d its last commit left: the commits after frame %d are"
                 " lost (it was truncated, removed or damaged since); restore a backup, or accept the store as it is"
                 " with surfd store recover",
                 name, header ? "holds" : "is gone, with", header && log > 0 ? log : 0, old.frames, kept);
        put(wm);
        return wm;
    }
    start(wm, log, ckpt);
    return wm;
}

const char *walmark_finding(const struct walmark *wm)
{
    return wm && wm->m.state == MARK_LOST ? wm->m.finding : NULL;
}

int walmark_accept(struct walmark *wm)
{
    if (!wm)
        return -1;
    int log = -1, ckpt = -1;
    sqlite3_wal_checkpoint_v2(wm->db, NULL, SQLITE_CHECKPOINT_PASSIVE, &log, &ckpt);
    start(wm, log, ckpt);
    return 0;
}

void walmark_closing(struct walmark *wm)
{
    if (!wm || wm->m.state == MARK_LOST)
        return;
    sqlite3_wal_hook(wm->db, NULL, NULL);
    wm->m.state = MARK_CLOSED;
    put(wm);
}

void walmark_free(struct walmark *wm)
{
    if (!wm)
        return;
    if (wm->fd >= 0)
        close(wm->fd); /* and its lock */
    free(wm);
}
