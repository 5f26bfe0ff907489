/* iges.c - IGES 5.3 files (fixed 80-column ASCII) to a scene of trimmed NURBS surfaces.
 *
 * Read: the Global section's delimiters, unit flag (coordinates become millimetres) and
 * Hollerith strings; the Directory's pairs of lines (status: unblanked entities are drawn unless
 * physically dependent, subordinate switch 01 or 03, which are drawn through their parents only;
 * logically dependent ones, 02, the members of a 402 group as CAD systems write them, are drawn as
 * independent ones are, and take the group's name where they have none; transform pointer; colour number or 314 pointer); parameter data with D
 * exponents. Entities: 128 rational B-spline surface; 126 B-spline curve, 110 line, 100 circular
 * arc, 102 composite curve and 106 copious data (forms 1, 2, 11, 12) as trim curves; 142 curve on
 * a surface (its parameter-space curve preferred, else the model-space curve projected onto the
 * surface); 144 trimmed surface (outer loop or the natural boundary, and holes); 141 boundary and
 * 143 bounded surface; 124 transforms (chained); 314 colours. A 128 that a 143/144 bounds is drawn
 * only trimmed, whatever its status says.
 *
 * Trim curves become polylines in the surface's (u, v) (core/geom/trim.h), sampled until the chord
 * is within TRIM_TOL_REL of the domain's size. Consecutive curves of a loop are joined end to end,
 * each turned round where its far end meets the loop (a SENSE flag in the wild is not always right);
 * a loop whose ends stay apart by more than LOOP_GAP_REL of its size is refused.
 *
 * Budget: before any loop is built, what every drawn surface's loops will hold is counted from what
 * the file declares (trim_budget): a B-spline curve's spans each sampled as deep as its second
 * derivative's control points need at the surface's tolerance, an arc's steps, a polyline's points,
 * a composite's constituents; a curve that several loops (or composites) use is counted at each use,
 * as each use is expanded anew, and its count memoized per entity so that nesting cannot make the
 * counting itself exponential. Over IGES_MAX_TRIM_POINTS the part is refused (SF_ELIMIT, 422) at the
 * surface where the count passed it; the points the loops then take are counted against the same
 * figure as they are made.
 *
 * Errors: text that is not IGES is 400 (SF_EFORMAT) naming the line; an entity that cannot be used
 * (a bad knot vector, missing U/V ranges, a loop that does not close, a pointer to nothing) is 422
 * (SF_EINVAL) with the pointer "D<n>", n the entity's first directory line.
 *
 * Written here: Open CASCADE reads IGES, but as a C++ toolkit of some hundred megabytes whose
 * B-rep would then have to be turned back into our surfaces; the format itself is small. */
#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "../core/base/mem.h"
#include "../core/geom/trim.h"
#include "iges.h"
#include "scene_io.h"

#define IGES_MAX_ENTITIES 1000000 /* directory entries */
#define IGES_MAX_DEPTH 16         /* nested composites and chained transforms */
#define CURVE_MAX_POINTS (1 << 20) /* control points of one curve */
#define TRIM_TOL_REL 4e-6         /* chord error of a trim polyline, of its surface's domain diagonal */
#define LOOP_GAP_REL 1e-2         /* largest gap in a loop, of the loop's size */
#define ARC_MAX_STEPS 4096
#define SAMPLE_MIN_DEPTH 3        /* a B-spline span is halved at least this often (8 chords): a wiggle within a
                                   * span that its ends and middle miss is still seen */
#define SAMPLE_MAX_DEPTH 14       /* and at most this often (16 384 chords a span) */
/* Trim points of all the surfaces' loops of one file, each use of a shared curve counted. A point
 * held costs some 20 bytes (its loop and its index; three times that while its loop is made) and
 * half a microsecond, so 2^23 is some 170 MB and 4 s of a job. The real parts count a few
 * thousand (mug_solid.igs, 13 faces: 6 156, of which 6 099 are made; mug.iges: 3 128): the figure
 * leaves three orders of magnitude for assemblies of thousands of faces, and twice the largest
 * loop one surface may hold (TRIM_MAX_POINTS). */
#define IGES_MAX_TRIM_POINTS (1u << 23)
#define POLL_POINTS 65536         /* trim points made between two polls of the job's cancel */
#define POLL_PROJECTED 1024       /* model-space points projected between two polls: each a Newton solve */
#define PROJECT_OFF_REL 2e-2      /* a model-space trim curve may lie this far off its surface, of its size
                                   * (exporters approximate: mug.iges's handle boundary is 0.6 % off) */

struct de { /* one directory entry */
    int type, param, n_lines, transform, color, form;
    int blank, sub;   /* status: blanked; subordinate switch (0 independent, 1 physically dependent,
                       * 2 logically dependent, 3 both) */
    int line;         /* its first D line: the entity's name in errors */
    char label[9];    /* the entity label (directory field 18), blanks trimmed */
    bool bounded;     /* a surface a 143/144 bounds */
    int group;        /* the 402 group it is a member of (its index), or -1 */
    char name[48];    /* a 402 group's: its 406 name, else its label (read_groups; as an object's) */
    /* the budget's memo (trim_budget): a curve's points at tolerance est_tol; a surface's tolerances */
    enum { EST_NONE, EST_BUSY, EST_DONE } est;
    double est_tol, est_points;
    bool tols_known;
    double tol_uv, tol_mm;
};

struct iges {
    char pd, rd;            /* parameter and record delimiters */
    double to_mm;
    struct de *de;
    int n_de;
    const char **p_line;    /* the P section's lines, by sequence number - 1 */
    int n_p;
    struct sf_err *err;
    const struct sf_progress *pr; /* polled while loops are made; NULL: never stops */
    double n_est;           /* trim points the loops will take, by trim_budget */
    double n_trim;          /* trim points the loops have taken so far */
};

/* ---- lines and fields ------------------------------------------------------------------ */

struct line {
    const char *s; /* 80 columns (shorter lines padded by the reader) */
    char section;
};

/* One parameter: a number, a Hollerith string (a pointer into the text), or empty. */
struct field {
    double num;       /* NAN unless a number */
    const char *str;  /* the string's first character, or NULL */
    int str_len;
    bool empty;
};

/* The parameters of one entity, or the Global section. */
struct params {
    char *text;
    struct field *f;
    int n;
    size_t cap;
};

static void params_free(struct params *p)
{
    free(p->text);
    free(p->f);
    memset(p, 0, sizeof *p);
}

/* Splits text (owned by p from now on) into fields by the delimiters, up to the record delimiter. */
static int split_fields(struct params *p, char *text, size_t len, char pd, char rd, const char *where,
                        struct sf_err *err)
{
    p->text = text;
    size_t k = 0;
    for (;;) {
        while (k < len && text[k] == ' ')
            k++;
        if (mem_reserve((void **)&p->f, &p->cap, (size_t)p->n + 1, sizeof *p->f))
            return sf_fail(err, SF_ENOMEM, where, "out of memory");
        int i = p->n++;
        struct field *fd = &p->f[i];
        *fd = (struct field){NAN, NULL, 0, false};
        size_t s = k;
        while (k < len && isdigit((unsigned char)text[k]))
            k++;
        if (k > s && k < len && text[k] == 'H') { /* Hollerith: nH then n characters */
            long n = strtol(text + s, NULL, 10);
            if (n < 0 || (size_t)n > len - k - 1)
                return sf_fail(err, SF_EFORMAT, where, "a Hollerith string runs past the parameters");
            fd->str = text + k + 1;
            fd->str_len = (int)n;
            k += 1 + (size_t)n;
        } else {
            while (k < len && text[k] != pd && text[k] != rd)
                k++;
            size_t e = k;
            while (e > s && text[e - 1] == ' ')
                e--;
            if (e == s) {
                fd->empty = true;
            } else {
                char num[64];
                if (e - s >= sizeof num)
                    return sf_fail(err, SF_EFORMAT, where, "parameter %d is not a number", i);
                for (size_t c = s; c < e; c++)
                    num[c - s] = text[c] == 'D' || text[c] == 'd' ? 'E' : text[c];
                num[e - s] = 0;
                char *end;
                errno = 0;
                double v = strtod(num, &end);
                if (*end || errno == ERANGE || !isfinite(v))
                    return sf_fail(err, SF_EFORMAT, where, "parameter %d (\"%s\") is not a number", i, num);
                fd->num = v;
            }
        }
        while (k < len && text[k] == ' ')
            k++;
        if (k >= len || text[k] == rd)
            return 0;
        if (text[k] != pd)
            return sf_fail(err, SF_EFORMAT, where, "parameter %d is followed by '%c', not a delimiter", i, text[k]);
        k++;
    }
}

/* Field accessors: k counts from 0 (the entity type). */
static bool p_num(const struct params *p, int k, double *v)
{
    if (k >= p->n || p->f[k].empty || p->f[k].str)
        return false;
    *v = p->f[k].num;
    return true;
}

static bool p_int(const struct params *p, int k, int *v)
{
    double d;
    if (!p_num(p, k, &d) || d != floor(d) || fabs(d) > 1e9)
        return false;
    *v = (int)d;
    return true;
}

static int p_int_or(const struct params *p, int k, int dflt)
{
    int v;
    return p_int(p, k, &v) ? v : dflt;
}

/* ---- directory and parameter sections --------------------------------------------------- */

static int field8(const char *s, int k, int *v) /* directory field k (0-8) of a line as an integer */
{
    char f[9];
    memcpy(f, s + 8 * k, 8);
    f[8] = 0;
    char *p = f;
    while (*p == ' ')
        p++;
    if (!*p) {
        *v = 0;
        return 0;
    }
    char *end;
    long n = strtol(p, &end, 10);
    while (*end == ' ')
        end++;
    if (*end || n > 1000000000L || n < -1000000000L)
        return -1;
    *v = (int)n;
    return 0;
}

static struct de *entity(struct iges *g, int ptr, const struct de *from, const char *what)
{
    if (ptr <= 0 || ptr % 2 == 0 || (ptr - 1) / 2 >= g->n_de) {
        char where[24];
        snprintf(where, sizeof where, "D%d", from ? from->line : 0);
        sf_fail(g->err, SF_EINVAL, where, "entity %d's %s points at directory line %d, which starts no entity",
                from ? from->type : 0, what, ptr);
        return NULL;
    }
    return &g->de[(ptr - 1) / 2];
}

static void where_of(const struct de *e, char where[24])
{
    snprintf(where, 24, "D%d", e->line);
}

static int load_params(struct iges *g, const struct de *e, struct params *p)
{
    char where[24];
    where_of(e, where);
    memset(p, 0, sizeof *p);
    if (e->param < 1 || e->n_lines < 1 || e->param - 1 > g->n_p - e->n_lines)
        return sf_fail(g->err, SF_EINVAL, where, "entity %d's parameter data (lines %d to %d) is not in the file",
                       e->type, e->param, e->param + e->n_lines - 1);
    size_t len = (size_t)e->n_lines * 64;
    char *text = malloc(len + 1);
    if (!text)
        return sf_fail(g->err, SF_ENOMEM, where, "out of memory");
    for (int k = 0; k < e->n_lines; k++)
        memcpy(text + 64 * k, g->p_line[e->param - 1 + k], 64);
    text[len] = 0;
    int rc = split_fields(p, text, len, g->pd, g->rd, where, g->err);
    int type;
    if (!rc && (!p_int(p, 0, &type) || type != e->type))
        rc = sf_fail(g->err, SF_EINVAL, where, "the parameter data of entity %d begins with another entity type",
                     e->type);
    if (rc)
        params_free(p);
    return rc;
}

/* ---- transforms (124) ------------------------------------------------------------------- */

struct xform {
    double r[3][3], t[3];
};

static void xform_identity(struct xform *x)
{
    memset(x, 0, sizeof *x);
    x->r[0][0] = x->r[1][1] = x->r[2][2] = 1.0;
}

static void xform_apply(const struct xform *x, const double in[3], double out[3])
{
    double o[3];
    for (int i = 0; i < 3; i++)
        o[i] = x->r[i][0] * in[0] + x->r[i][1] * in[1] + x->r[i][2] * in[2] + x->t[i];
    memcpy(out, o, sizeof o);
}

/* The transform of entity e (its 124 chain composed, outermost last), identity when it has none. */
static int entity_xform(struct iges *g, const struct de *e, struct xform *x)
{
    xform_identity(x);
    const struct de *at = e;
    for (int depth = 0; at->transform; depth++) {
        char where[24];
        where_of(e, where);
        if (depth >= IGES_MAX_DEPTH)
            return sf_fail(g->err, SF_EINVAL, where, "transforms chained deeper than %d", IGES_MAX_DEPTH);
        const struct de *t = entity(g, at->transform, at, "transform");
        if (!t)
            return SF_EINVAL;
        if (t->type != 124)
            return sf_fail(g->err, SF_EINVAL, where, "the transform pointer names entity type %d, not 124", t->type);
        struct params p;
        int rc = load_params(g, t, &p);
        if (rc)
            return rc;
        struct xform m;
        for (int i = 0; i < 3 && !rc; i++)
            for (int j = 0; j < 4 && !rc; j++) {
                double v;
                if (!p_num(&p, 1 + 4 * i + j, &v)) {
                    where_of(t, where);
                    rc = sf_fail(g->err, SF_EINVAL, where, "transform matrix element %d is missing", 4 * i + j + 1);
                } else if (j < 3) {
                    m.r[i][j] = v;
                } else {
                    m.t[i] = v;
                }
            }
        params_free(&p);
        if (rc)
            return rc;
        struct xform c; /* m after x */
        for (int i = 0; i < 3; i++) {
            for (int j = 0; j < 3; j++)
                c.r[i][j] = m.r[i][0] * x->r[0][j] + m.r[i][1] * x->r[1][j] + m.r[i][2] * x->r[2][j];
            c.t[i] = m.r[i][0] * x->t[0] + m.r[i][1] * x->t[1] + m.r[i][2] * x->t[2] + m.t[i];
        }
        *x = c;
        at = t;
    }
    return 0;
}

/* ---- curves to polylines ---------------------------------------------------------------- */

struct poly {
    double (*p)[3];
    size_t n, cap;
};

/* sf_poll with the share of the estimated trim points made so far, extra of them not yet counted. */
static int poll_cancel(struct iges *g, size_t extra)
{
    return sf_poll(g->pr, g->n_est > 0 ? fmin(1.0, (g->n_trim + (double)extra) / g->n_est) : 0, g->err);
}

static int poly_add(struct iges *g, struct poly *pl, const double q[3], const char *where)
{
    if (pl->n >= TRIM_MAX_POINTS)
        return sf_fail(g->err, SF_ELIMIT, where, "trim curves need more than %u points", TRIM_MAX_POINTS);
    int rc;
    if (pl->n && pl->n % POLL_POINTS == 0 && (rc = poll_cancel(g, pl->n)))
        return rc;
    if (mem_reserve((void **)&pl->p, &pl->cap, pl->n + 1, sizeof *pl->p))
        return sf_fail(g->err, SF_ENOMEM, where, "out of memory");
    memcpy(pl->p[pl->n++], q, sizeof *pl->p);
    return 0;
}

struct bcurve {
    int deg, n;
    double *knots, *w, (*cp)[3];
    double t0, t1;
};

static void bcurve_eval(const struct bcurve *c, double t, double out[3])
{
    double N[PATCH_MAX_DEGREE + 1];
    int r = nurbs_basis(c->knots, c->n, c->deg, t, N);
    double s[4] = {0, 0, 0, 0};
    for (int k = 0; k <= c->deg; k++) {
        int i = r - c->deg + k;
        double w = c->w ? c->w[i] : 1.0;
        for (int d = 0; d < 3; d++)
            s[d] += N[k] * w * c->cp[i][d];
        s[3] += N[k] * w;
    }
    for (int d = 0; d < 3; d++)
        out[d] = s[d] / s[3];
}

static double dist3(const double a[3], const double b[3])
{
    return sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2]));
}

/* Points of c on (a, b] until each chord is within tol of the curve at its middle. */
static int bcurve_sample(struct iges *g, const struct bcurve *c, double a, const double pa[3], double b,
                         const double pb[3], double tol, int depth, struct poly *pl, const char *where)
{
    double m = 0.5 * (a + b), pm[3], mid[3];
    bcurve_eval(c, m, pm);
    for (int d = 0; d < 3; d++)
        mid[d] = 0.5 * (pa[d] + pb[d]);
    if (depth < SAMPLE_MIN_DEPTH || (depth < SAMPLE_MAX_DEPTH && dist3(pm, mid) > tol)) {
        int rc = bcurve_sample(g, c, a, pa, m, pm, tol, depth + 1, pl, where);
        return rc ? rc : bcurve_sample(g, c, m, pm, b, pb, tol, depth + 1, pl, where);
    }
    return poly_add(g, pl, pb, where);
}

static void bcurve_free(struct bcurve *c)
{
    free(c->knots);
    free(c->w);
    free(c->cp);
    memset(c, 0, sizeof *c);
}

/* The B-spline curve of 126 entity e (parameters p), after its transform; caller frees c with
 * bcurve_free(), also on failure. */
static int bcurve_read(struct iges *g, const struct de *e, const struct params *p, struct bcurve *c,
                       const char *where)
{
    memset(c, 0, sizeof *c);
    int K, M;
    if (!p_int(p, 1, &K) || !p_int(p, 2, &M) || M < 1 || M > PATCH_MAX_DEGREE || K < M || K >= CURVE_MAX_POINTS)
        return sf_fail(g->err, SF_EINVAL, where, "B-spline curve: upper index K and degree M must satisfy 1 <= M <= K "
                       "(M at most %d)", PATCH_MAX_DEGREE);
    int n = K + 1, nk = K + M + 2, at = 7;
    if (p->n < at + nk + n + 3 * n + 2)
        return sf_fail(g->err, SF_EINVAL, where, "B-spline curve: %d parameters, %d needed (knots, weights, points, "
                       "V(0), V(1))", p->n - 1, at + nk + n + 3 * n + 2 - 1);
    *c = (struct bcurve){M, n, malloc(sizeof(double) * (size_t)nk), malloc(sizeof(double) * (size_t)n),
                         malloc(sizeof(double[3]) * (size_t)n), 0, 0};
    int rc = 0;
    if (!c->knots || !c->w || !c->cp)
        rc = sf_fail(g->err, SF_ENOMEM, where, "out of memory");
    for (int k = 0; k < nk && !rc; k++)
        if (!p_num(p, at + k, &c->knots[k]) || (k && c->knots[k] < c->knots[k - 1]))
            rc = sf_fail(g->err, SF_EINVAL, where, "B-spline curve: knot %d is missing or decreases", k);
    for (int k = 0; k < n && !rc; k++)
        if (!p_num(p, at + nk + k, &c->w[k]) || !(c->w[k] > 0))
            rc = sf_fail(g->err, SF_EINVAL, where, "B-spline curve: weight %d is missing or not positive", k);
    for (int k = 0; k < 3 * n && !rc; k++)
        if (!p_num(p, at + nk + n + k, &c->cp[k / 3][k % 3]))
            rc = sf_fail(g->err, SF_EINVAL, where, "B-spline curve: control point coordinate %d is missing", k);
    if (!rc && (!p_num(p, at + nk + 4 * n, &c->t0) || !p_num(p, at + nk + 4 * n + 1, &c->t1)))
        rc = sf_fail(g->err, SF_EINVAL, where, "B-spline curve: its parameter range V(0), V(1) is missing");
    if (!rc && !(c->t0 < c->t1 && c->t0 >= c->knots[M] - 1e-9 * fabs(c->knots[n] - c->knots[M]) &&
                 c->t1 <= c->knots[n] + 1e-9 * fabs(c->knots[n] - c->knots[M])))
        rc = sf_fail(g->err, SF_EINVAL, where, "B-spline curve: parameter range [%g, %g] is not within its knots [%g, %g]",
                     c->t0, c->t1, c->knots[M], c->knots[n]);
    if (!rc) {
        c->t0 = fmax(c->t0, c->knots[M]), c->t1 = fmin(c->t1, c->knots[n]);
        struct xform x;
        rc = entity_xform(g, e, &x);
        for (int k = 0; k < n && !rc; k++)
            xform_apply(&x, c->cp[k], c->cp[k]);
    }
    return rc;
}

/* The next piece c is sampled in, span by span so that no span is passed over: from *a (where the
 * last one ended, c->t0 at first) to *b, within knot span *s (knots[s] to knots[s + 1]); *k is the
 * knot to look at next (c->deg + 1 at first). False when no piece is left. */
static bool bcurve_piece(const struct bcurve *c, int *k, double *a, double *b, int *s)
{
    for (; *k <= c->n && *a < c->t1; ++*k) {
        *b = fmin(c->knots[*k], c->t1);
        if (*b > *a) {
            *s = *k - 1;
            ++*k;
            return true;
        }
    }
    return false;
}

static int curve_126(struct iges *g, const struct de *e, const struct params *p, double tol, struct poly *pl,
                     const char *where)
{
    struct bcurve c;
    int rc = bcurve_read(g, e, p, &c, where);
    double a = c.t0, b, pa[3];
    if (!rc) {
        bcurve_eval(&c, a, pa);
        rc = poly_add(g, pl, pa, where);
    }
    for (int k = c.deg + 1, s; !rc && bcurve_piece(&c, &k, &a, &b, &s); a = b) {
        double pb[3];
        bcurve_eval(&c, nextafter(b, a), pb); /* the span's own end, from inside it */
        rc = bcurve_sample(g, &c, a, pa, b, pb, tol, 0, pl, where);
        memcpy(pa, pb, sizeof pa);
    }
    bcurve_free(&c);
    return rc;
}

/* The points curve_126 gives c at tol, from above: bcurve_sample halves a piece of length h until
 * the chord's middle is within tol of the curve's, which holds once h^2 / 8 max|C''| <= tol; |C''|
 * is bounded on a span by its second-derivative control points (Piegl and Tiller, The NURBS Book,
 * eq. 3.9: C'' lies in their hull), per coordinate. A rational span's bound is that of its points
 * times (w_max / w_min)^2: an estimate there, not a bound (the points made are counted too). */
static double bcurve_estimate(const struct bcurve *c, double tol)
{
    const int M = c->deg;
    const double *U = c->knots;
    double n = 1, a = c->t0, b;
    for (int k = M + 1, s; bcurve_piece(c, &k, &a, &b, &s); a = b) {
        double d2[3] = {0, 0, 0}, wlo = INFINITY, whi = 0;
        for (int i = s - M; i <= s - 2; i++) { /* R_i, of Q_i and Q_i+1 (the first derivative's) */
            double du = U[i + M + 1] - U[i + 2];
            if (!(du > 0))
                continue; /* its basis function is zero on every span */
            double dq0 = U[i + M + 1] - U[i + 1], dq1 = U[i + M + 2] - U[i + 2];
            for (int d = 0; d < 3; d++) {
                double q0 = M * (c->cp[i + 1][d] - c->cp[i][d]) / dq0;
                double q1 = M * (c->cp[i + 2][d] - c->cp[i + 1][d]) / dq1;
                d2[d] = fmax(d2[d], fabs((M - 1) * (q1 - q0) / du));
            }
        }
        for (int i = s - M; c->w && i <= s; i++)
            wlo = fmin(wlo, c->w[i]), whi = fmax(whi, c->w[i]);
        double bound = sqrt(d2[0] * d2[0] + d2[1] * d2[1] + d2[2] * d2[2]) * (c->w ? (whi / wlo) * (whi / wlo) : 1);
        double need = (b - a) * sqrt(bound / (8 * tol)); /* chords a piece needs */
        int depth = SAMPLE_MIN_DEPTH;
        while (depth < SAMPLE_MAX_DEPTH && !(ldexp(1.0, depth) >= need)) /* NaN, inf: the deepest */
            depth++;
        n += ldexp(1.0, depth);
    }
    return n;
}

/* A circular arc (100): centre, radius, angles and the n steps (n + 1 points) that keep its chords
 * within tol. */
struct arc {
    double zt, cx, cy, r, a0, a1;
    int n;
};

static int arc_read(struct iges *g, const struct params *p, double tol, struct arc *c, const char *where)
{
    double v[7];
    for (int k = 0; k < 7; k++)
        if (!p_num(p, 1 + k, &v[k]))
            return sf_fail(g->err, SF_EINVAL, where, "circular arc: parameter %d is missing", k + 1);
    c->zt = v[0], c->cx = v[1], c->cy = v[2], c->r = hypot(v[3] - c->cx, v[4] - c->cy);
    c->a0 = atan2(v[4] - c->cy, v[3] - c->cx), c->a1 = atan2(v[6] - c->cy, v[5] - c->cx);
    if (!(c->r > 0))
        return sf_fail(g->err, SF_EINVAL, where, "circular arc: its radius is zero");
    if (c->a1 <= c->a0 + 1e-12)
        c->a1 += 2 * M_PI;
    double step = 2 * acos(fmax(-1.0, 1.0 - fmin(tol / c->r, 1.0)));
    c->n = (int)fmin(ARC_MAX_STEPS, fmax(4.0, ceil((c->a1 - c->a0) / fmax(step, 1e-6))));
    return 0;
}

/* A copious data entity's (106) point layout (ip: 1 for (x, y) at a common z, 2 for (x, y, z)) and
 * count n. */
static int copious_count(struct iges *g, const struct de *e, const struct params *p, int *ip, int *n,
                         const char *where)
{
    if ((e->form != 1 && e->form != 2 && e->form != 11 && e->form != 12) || !p_int(p, 1, ip) || !p_int(p, 2, n) ||
        (*ip != 1 && *ip != 2) || *n < 2 || *n > CURVE_MAX_POINTS)
        return sf_fail(g->err, SF_EINVAL, where, "copious data form %d: only point lists (forms 1, 2, 11, 12) of "
                       "at least 2 points trim", e->form);
    return 0;
}

static int curve_points(struct iges *g, const struct de *e, double tol, int depth, struct poly *pl);

static int curve_params(struct iges *g, const struct de *e, const struct params *p, double tol, int depth,
                        struct poly *pl)
{
    char where[24];
    where_of(e, where);
    struct xform x;
    int rc;
    switch (e->type) {
    case 126: return curve_126(g, e, p, tol, pl, where);
    case 110: { /* line */
        double a[3], b[3];
        for (int k = 0; k < 3; k++)
            if (!p_num(p, 1 + k, &a[k]) || !p_num(p, 4 + k, &b[k]))
                return sf_fail(g->err, SF_EINVAL, where, "line: its end points are missing");
        if (e->form != 0)
            return sf_fail(g->err, SF_EINVAL, where, "line form %d (a ray or unbounded line) bounds no region", e->form);
        if ((rc = entity_xform(g, e, &x)))
            return rc;
        xform_apply(&x, a, a);
        xform_apply(&x, b, b);
        return (rc = poly_add(g, pl, a, where)) ? rc : poly_add(g, pl, b, where);
    }
    case 100: { /* arc in the plane z = ZT of its definition space, counter-clockwise from start to end */
        struct arc c;
        if ((rc = arc_read(g, p, tol, &c, where)) || (rc = entity_xform(g, e, &x)))
            return rc;
        for (int k = 0; k <= c.n && !rc; k++) {
            double a = c.a0 + (c.a1 - c.a0) * k / c.n, q[3] = {c.cx + c.r * cos(a), c.cy + c.r * sin(a), c.zt};
            xform_apply(&x, q, q);
            rc = poly_add(g, pl, q, where);
        }
        return rc;
    }
    case 106: { /* copious data: points (forms 1, 2) or a polyline (11, 12) */
        int ip, n;
        if ((rc = copious_count(g, e, p, &ip, &n, where)))
            return rc;
        double zt = 0;
        int at = 3;
        if (ip == 1 && !p_num(p, at++, &zt))
            return sf_fail(g->err, SF_EINVAL, where, "copious data: its common z is missing");
        if ((rc = entity_xform(g, e, &x)))
            return rc;
        int stride = ip == 1 ? 2 : 3;
        for (int k = 0; k < n && !rc; k++) {
            double q[3] = {0, 0, zt};
            for (int d = 0; d < stride; d++)
                if (!p_num(p, at + stride * k + d, &q[d]))
                    return sf_fail(g->err, SF_EINVAL, where, "copious data: point %d is missing", k);
            xform_apply(&x, q, q);
            rc = poly_add(g, pl, q, where);
        }
        return rc;
    }
    case 102: { /* composite curve: its constituents end to end */
        int n;
        if (!p_int(p, 1, &n) || n < 1 || n > p->n - 2)
            return sf_fail(g->err, SF_EINVAL, where, "composite curve: its count of constituents is missing or wrong");
        if (depth >= IGES_MAX_DEPTH)
            return sf_fail(g->err, SF_EINVAL, where, "composite curves nested deeper than %d", IGES_MAX_DEPTH);
        const size_t start = pl->n;
        for (int k = 0; k < n; k++) {
            int ptr;
            const struct de *c;
            if (!p_int(p, 2 + k, &ptr) || !(c = entity(g, ptr, e, "constituent")))
                return SF_EINVAL;
            size_t from = pl->n;
            if ((rc = curve_points(g, c, tol, depth + 1, pl)))
                return rc;
            if (from > 0 && pl->n - from >= 2) { /* turned round where its far end meets the curve so far */
                const double *last = pl->p[from - 1];
                if (dist3(last, pl->p[pl->n - 1]) < dist3(last, pl->p[from]))
                    for (size_t i = from, j = pl->n - 1; i < j; i++, j--) {
                        double t[3];
                        memcpy(t, pl->p[i], sizeof t);
                        memcpy(pl->p[i], pl->p[j], sizeof t);
                        memcpy(pl->p[j], t, sizeof t);
                    }
            }
        }
        if ((rc = entity_xform(g, e, &x))) /* the composite's own transform, after its constituents' */
            return rc;
        for (size_t k = start; k < pl->n; k++)
            xform_apply(&x, pl->p[k], pl->p[k]);
        return 0;
    }
    default:
        return sf_fail(g->err, SF_EINVAL, where, "entity type %d is not a trim curve (126, 110, 100, 102 or 106)",
                       e->type);
    }
}

/* Appends the points of curve e (in its own space, after its transform) to pl. */
static int curve_points(struct iges *g, const struct de *e, double tol, int depth, struct poly *pl)
{
    struct params p;
    int rc = load_params(g, e, &p);
    if (!rc)
        rc = curve_params(g, e, &p, tol, depth, pl);
    params_free(&p);
    return rc;
}

/* Adds to *n the points curve_points gives e at tol: from above where bcurve_estimate can tell, as
 * many as it makes for the others. Errors as curve_points has them, where they would stop the count;
 * an entity it cannot use counts nothing (curve_points refuses it). Memoized per entity at one
 * tolerance, so that a curve named by many composites, or composites nested each naming the one
 * below many times, take time linear in the file. */
static int curve_estimate(struct iges *g, struct de *e, double tol, int depth, double *n)
{
    char where[24];
    where_of(e, where);
    if (e->est == EST_DONE && e->est_tol == tol) {
        *n += e->est_points;
        return 0;
    }
    if (e->est == EST_BUSY) /* a composite within itself: as deep as curve_points would go */
        return sf_fail(g->err, SF_EINVAL, where, "composite curves nested deeper than %d", IGES_MAX_DEPTH);
    struct params p;
    int rc = load_params(g, e, &p);
    if (rc)
        return rc;
    e->est = EST_BUSY;
    double m = 0;
    switch (e->type) {
    case 126: {
        struct bcurve c;
        if (!(rc = bcurve_read(g, e, &p, &c, where)))
            m = bcurve_estimate(&c, tol);
        bcurve_free(&c);
        break;
    }
    case 110:
        m = 2;
        break;
    case 100: {
        struct arc c;
        if (!(rc = arc_read(g, &p, tol, &c, where)))
            m = c.n + 1;
        break;
    }
    case 106: {
        int ip, k;
        if (!(rc = copious_count(g, e, &p, &ip, &k, where)))
            m = k;
        break;
    }
    case 102:
        if (depth >= IGES_MAX_DEPTH) {
            rc = sf_fail(g->err, SF_EINVAL, where, "composite curves nested deeper than %d", IGES_MAX_DEPTH);
            break;
        }
        for (int k = 0, n_c = p_int_or(&p, 1, 0); k < n_c && k < p.n - 2 && !rc; k++) {
            struct de *c = entity(g, p_int_or(&p, 2 + k, 0), e, "constituent");
            rc = c ? curve_estimate(g, c, tol, depth + 1, &m) : SF_EINVAL;
        }
        break;
    }
    params_free(&p);
    e->est = rc ? EST_NONE : EST_DONE;
    e->est_tol = tol, e->est_points = m;
    *n += m;
    return rc;
}

/* ---- surfaces (128) --------------------------------------------------------------------- */

/* The surface of entity e (a 128), in millimetres after its transform, and its U/V ranges. */
static int read_surface(struct iges *g, const struct de *e, struct surface *s, double dom[4])
{
    char where[24];
    where_of(e, where);
    memset(s, 0, sizeof *s);
    if (e->type != 128)
        return sf_fail(g->err, SF_EINVAL, where, "entity type %d is not a rational B-spline surface (128), the one "
                       "surface surfd reads", e->type);
    struct params p;
    int rc = load_params(g, e, &p);
    if (rc)
        return rc;
    int K1, K2, M1, M2;
    if (!p_int(&p, 1, &K1) || !p_int(&p, 2, &K2) || !p_int(&p, 3, &M1) || !p_int(&p, 4, &M2) || M1 < 1 || M2 < 1 ||
        M1 > PATCH_MAX_DEGREE || M2 > PATCH_MAX_DEGREE || K1 < M1 || K2 < M2) {
        params_free(&p);
        return sf_fail(g->err, SF_EINVAL, where, "B-spline surface: upper indices K1, K2 and degrees M1, M2 must "
                       "satisfy 1 <= M <= K (degrees at most %d)", PATCH_MAX_DEGREE);
    }
    if ((double)(K1 + 1) * (K2 + 1) > SURF_MAX_POINTS) {
        params_free(&p);
        return sf_fail(g->err, SF_ELIMIT, where, "B-spline surface: %d x %d control points, over the limit of %d",
                       K1 + 1, K2 + 1, SURF_MAX_POINTS);
    }
    int nu = K1 + 1, nv = K2 + 1, nku = K1 + M1 + 2, nkv = K2 + M2 + 2, c = nu * nv;
    int at_ku = 10, at_kv = at_ku + nku, at_w = at_kv + nkv, at_p = at_w + c, at_d = at_p + 3 * c;
    if (p.n < at_d) {
        params_free(&p);
        return sf_fail(g->err, SF_EINVAL, where, "B-spline surface: %d parameters, %d needed for its knots, weights "
                       "and points", p.n - 1, at_d - 1);
    }
    bool rational = false;
    double w0 = p.f[at_w].num;
    for (int k = 0; k < c; k++)
        rational |= !(p.f[at_w + k].num == w0);
    if ((rc = nurbs_surface_alloc(s, rational ? SURF_NURBS : SURF_BSPLINE, M1, M2, nu, nv, g->err))) {
        params_free(&p);
        return rc;
    }
    for (int k = 0; k < nku && !rc; k++)
        if (!p_num(&p, at_ku + k, &s->knots_u[k]))
            rc = sf_fail(g->err, SF_EINVAL, where, "B-spline surface: knot %d along u is missing", k);
    for (int k = 0; k < nkv && !rc; k++)
        if (!p_num(&p, at_kv + k, &s->knots_v[k]))
            rc = sf_fail(g->err, SF_EINVAL, where, "B-spline surface: knot %d along v is missing", k);
    struct xform x;
    if (!rc)
        rc = entity_xform(g, e, &x);
    for (int j = 0; j < nv && !rc; j++) /* IGES runs u fastest; ours is row-major along u */
        for (int i = 0; i < nu && !rc; i++) {
            int src = j * nu + i, dst = i * nv + j;
            double q[3];
            for (int d = 0; d < 3 && !rc; d++)
                if (!p_num(&p, at_p + 3 * src + d, &q[d]))
                    rc = sf_fail(g->err, SF_EINVAL, where, "B-spline surface: control point (%d, %d) is missing", i, j);
            if (rc)
                break;
            xform_apply(&x, q, q);
            for (int d = 0; d < 3; d++)
                s->points[3 * dst + d] = q[d] * g->to_mm;
            if (rational && !p_num(&p, at_w + src, &s->weights[dst]))
                rc = sf_fail(g->err, SF_EINVAL, where, "B-spline surface: weight (%d, %d) is missing", i, j);
        }
    if (!rc)
        rc = nurbs_validate(s, where, g->err);
    double k0, k1, l0, l1;
    if (!rc) {
        nurbs_domain(s, &k0, &k1, &l0, &l1);
        for (int k = 0; k < 4 && !rc; k++)
            if (!p_num(&p, at_d + k, &dom[k]))
                rc = sf_fail(g->err, SF_EINVAL, where, "B-spline surface: its parameter ranges U(0), U(1), V(0), V(1) "
                             "are missing");
    }
    if (!rc) {
        double eu = 1e-9 * (k1 - k0), ev = 1e-9 * (l1 - l0);
        if (!(dom[0] < dom[1] && dom[2] < dom[3] && dom[0] >= k0 - eu && dom[1] <= k1 + eu && dom[2] >= l0 - ev &&
              dom[3] <= l1 + ev))
            rc = sf_fail(g->err, SF_EINVAL, where, "B-spline surface: parameter ranges [%g, %g] x [%g, %g] are not "
                         "within its knots [%g, %g] x [%g, %g]", dom[0], dom[1], dom[2], dom[3], k0, k1, l0, l1);
        dom[0] = fmax(dom[0], k0), dom[1] = fmin(dom[1], k1), dom[2] = fmax(dom[2], l0), dom[3] = fmin(dom[3], l1);
    }
    params_free(&p);
    if (rc)
        nurbs_surface_free(s);
    return rc;
}

/* What a loop's pieces are drawn on. */
struct on_surface {
    const struct surface *s;
    double dom[4];
    double tol_uv;   /* chord error of a parameter-space piece */
    double tol_mm;   /* of a model-space piece */
    double size_mm;  /* the surface's control hull diagonal */
    bool closed[2];  /* it closes along u, along v (closes()) */
};

/* The parameters (u, v) of the surface point nearest P: Gauss–Newton from uv (seeded) or from the
 * nearest point of a coarse grid; *dist is what remains. */
static void invert(const struct on_surface *on, const double P[3], double uv[2], bool seeded, double *dist)
{
    const struct surface *s = on->s;
    const double *dom = on->dom;
    const vec3 q = v3(P[0], P[1], P[2]);
    vec3 S, Su, Sv;
    for (int pass = seeded ? 0 : 1; pass < 2; pass++) {
        if (pass == 1) { /* the grid's nearest point */
            double best = INFINITY;
            enum { G = 24 };
            for (int i = 0; i <= G; i++)
                for (int j = 0; j <= G; j++) {
                    double u = dom[0] + (dom[1] - dom[0]) * i / G, v = dom[2] + (dom[3] - dom[2]) * j / G;
                    nurbs_eval(s, u, v, &S, NULL, NULL);
                    double d = v3_len(v3_sub(S, q));
                    if (d < best)
                        best = d, uv[0] = u, uv[1] = v;
                }
        }
        for (int it = 0; it < 30; it++) {
            nurbs_eval(s, uv[0], uv[1], &S, &Su, &Sv);
            vec3 r = v3_sub(q, S);
            double a = v3_dot(Su, Su), b = v3_dot(Su, Sv), c = v3_dot(Sv, Sv), det = a * c - b * b;
            if (!(det > 0))
                break;
            double ru = v3_dot(Su, r), rv = v3_dot(Sv, r);
            double du = (c * ru - b * rv) / det, dv = (a * rv - b * ru) / det;
            const double step[2] = {du, dv};
            for (int d = 0; d < 2; d++) { /* across a closed surface's seam: on round it */
                double lo = dom[2 * d], hi = dom[2 * d + 1], x = uv[d] + step[d];
                uv[d] = on->closed[d] ? (x < lo ? x + (hi - lo) : x > hi ? x - (hi - lo) : x) : fmin(hi, fmax(lo, x));
                uv[d] = fmin(hi, fmax(lo, uv[d]));
            }
            if (fabs(du) < 1e-14 * (dom[1] - dom[0]) && fabs(dv) < 1e-14 * (dom[3] - dom[2]))
                break;
        }
        nurbs_eval(s, uv[0], uv[1], &S, NULL, NULL);
        *dist = v3_len(v3_sub(S, q));
        if (*dist <= 1e-6 * on->size_mm)
            return;
    }
}

/* ---- trim loops ------------------------------------------------------------------------- */

struct loops {
    double (*uv)[2];
    size_t n, cap;
    size_t *counts;
    size_t n_loops, cap_loops;
};

static void loops_free(struct loops *l)
{
    free(l->uv);
    free(l->counts);
    memset(l, 0, sizeof *l);
}


/* Whether the surface closes along direction d (0: u, 1: v): its two edges across d coincide. */
static bool closes(const struct on_surface *on, int d)
{
    for (int k = 0; k <= 4; k++) {
        double t = on->dom[2 - 2 * d] + (on->dom[3 - 2 * d] - on->dom[2 - 2 * d]) * k / 4;
        vec3 a, b;
        if (d == 0) {
            nurbs_eval(on->s, on->dom[0], t, &a, NULL, NULL);
            nurbs_eval(on->s, on->dom[1], t, &b, NULL, NULL);
        } else {
            nurbs_eval(on->s, t, on->dom[2], &a, NULL, NULL);
            nurbs_eval(on->s, t, on->dom[3], &b, NULL, NULL);
        }
        if (v3_len(v3_sub(a, b)) > 1e-6 * on->size_mm)
            return false;
    }
    return true;
}

/* A projected point on the seam of a closed surface may take either side's parameter: each such
 * point takes the side of its nearest point off the seam in the piece, and a piece lying wholly on
 * the seam (a boundary that runs up the seam and back, as a closed surface's natural boundary does)
 * one side: the one nearer the loop's end, or for a loop's first piece the side it starts on. */
static void seam_sides(const struct on_surface *on, double (*uv)[2], size_t n, const double *loop_end)
{
    for (int d = 0; d < 2; d++) {
        if (!on->closed[d])
            continue;
        const double lo = on->dom[2 * d], hi = on->dom[2 * d + 1], eps = 1e-6 * (hi - lo);
#define ON_SEAM(k) (fabs(uv[k][d] - lo) <= eps || fabs(uv[k][d] - hi) <= eps)
        size_t off = 0;
        while (off < n && ON_SEAM(off))
            off++;
        if (off == n) {
            const double at = loop_end ? loop_end[d] : uv[0][d]; /* else the side it starts on */
            for (size_t k = 0; k < n; k++)
                uv[k][d] = fabs(at - lo) < fabs(at - hi) ? lo : hi;
            continue;
        }
        for (size_t k = 0; k < n; k++) {
            if (!ON_SEAM(k))
                continue;
            size_t near = k; /* the nearest point off the seam, before or after */
            for (size_t j = 1; j < n; j++) {
                if (k >= j && !ON_SEAM(k - j)) {
                    near = k - j;
                    break;
                }
                if (k + j < n && !ON_SEAM(k + j)) {
                    near = k + j;
                    break;
                }
            }
            uv[k][d] = fabs(uv[near][d] - lo) < fabs(uv[near][d] - hi) ? lo : hi;
        }
#undef ON_SEAM
    }
}

/* Appends piece (points in the surface's (u, v), or in model space to be projected) to the loop
 * being built from loop_start on, turned round where its far end meets the loop. */
static int loop_add(struct iges *g, struct loops *l, size_t loop_start, struct poly *piece, bool model, bool reverse,
                    const struct on_surface *on, const struct de *owner)
{
    char where[24];
    where_of(owner, where);
    if (piece->n == 0)
        return 0;
    double (*uv)[2] = malloc(sizeof *uv * piece->n);
    if (!uv)
        return sf_fail(g->err, SF_ENOMEM, where, "out of memory");
    int rc = 0;
    for (size_t k = 0; k < piece->n; k++) {
        if (!model) {
            uv[k][0] = piece->p[k][0], uv[k][1] = piece->p[k][1];
            continue;
        }
        if (k && k % POLL_PROJECTED == 0 && (rc = poll_cancel(g, k))) {
            free(uv);
            return rc;
        }
        double P[3] = {piece->p[k][0] * g->to_mm, piece->p[k][1] * g->to_mm, piece->p[k][2] * g->to_mm}, d;
        const double *seed = k ? uv[k - 1] : l->n > loop_start ? l->uv[l->n - 1] : NULL; /* the point before */
        if (seed)
            uv[k][0] = seed[0], uv[k][1] = seed[1];
        invert(on, P, uv[k], seed != NULL, &d);
        if (d > PROJECT_OFF_REL * on->size_mm) {
            free(uv);
            return sf_fail(g->err, SF_EINVAL, where, "a model-space trim curve lies %.3g mm off its surface (at %g, %g, "
                           "%g)", d, P[0], P[1], P[2]);
        }
    }
    const double diag = hypot(on->dom[1] - on->dom[0], on->dom[3] - on->dom[2]);
    size_t n = piece->n;
    if (model)
        seam_sides(on, uv, n, l->n > loop_start ? l->uv[l->n - 1] : NULL);
    if (l->n > loop_start) {
        const double *end = l->uv[l->n - 1];
        double d0 = hypot(uv[0][0] - end[0], uv[0][1] - end[1]), d1 = hypot(uv[n - 1][0] - end[0], uv[n - 1][1] - end[1]);
        reverse = d1 < d0;
        if (fmin(d0, d1) > LOOP_GAP_REL * diag) {
            free(uv);
            return sf_fail(g->err, SF_EINVAL, where, "a trim loop's curves do not meet: a gap of %.3g in (u, v), %.2g "
                           "of the domain", fmin(d0, d1), fmin(d0, d1) / diag);
        }
    }
    for (size_t k = 0; k < n && !rc; k++) {
        if (k && k % POLL_POINTS == 0 && (rc = poll_cancel(g, n - k))) /* (as counted: the piece's points) */
            break;
        const double *q = uv[reverse ? n - 1 - k : k];
        if (l->n > loop_start && q[0] == l->uv[l->n - 1][0] && q[1] == l->uv[l->n - 1][1])
            continue;
        if (l->n >= TRIM_MAX_POINTS)
            rc = sf_fail(g->err, SF_ELIMIT, where, "trim loops need more than %u points", TRIM_MAX_POINTS);
        else if (g->n_trim >= IGES_MAX_TRIM_POINTS) /* past trim_budget's count: a rational curve's estimate */
            rc = sf_fail(g->err, SF_ELIMIT, where, "the surfaces' trim loops take more than the budget of %u trim "
                         "points", IGES_MAX_TRIM_POINTS);
        else if (mem_reserve((void **)&l->uv, &l->cap, l->n + 1, sizeof *l->uv))
            rc = sf_fail(g->err, SF_ENOMEM, where, "out of memory");
        else
            l->uv[l->n][0] = q[0], l->uv[l->n][1] = q[1], l->n++, g->n_trim++;
    }
    free(uv);
    return rc;
}

/* In trim_budget's count: n more points of owner's loops, refused once the count is past the budget. */
static int budget_add(struct iges *g, double n, const struct de *owner)
{
    g->n_est += n;
    if (g->n_est <= IGES_MAX_TRIM_POINTS)
        return 0;
    char where[24];
    where_of(owner, where);
    return sf_fail(g->err, SF_ELIMIT, where, "the surfaces' trim loops come to %.0f points with this one's %.0f (a "
                   "curve is counted at each use, as each use is made anew), over the budget of %u trim points",
                   g->n_est, n, IGES_MAX_TRIM_POINTS);
}

/* Closes the loop begun at loop_start: its ends must meet. l NULL (trim_budget's count): the loop's
 * points, counted into g->n_est since it was before, are held against the budget at owner. */
static int loop_close(struct iges *g, struct loops *l, size_t loop_start, double before, const struct de *owner)
{
    if (!l) {
        double n = g->n_est - before;
        g->n_est = before;
        return budget_add(g, n, owner);
    }
    char where[24];
    where_of(owner, where);
    size_t n = l->n - loop_start;
    double lo[2] = {INFINITY, INFINITY}, hi[2] = {-INFINITY, -INFINITY};
    for (size_t k = loop_start; k < l->n; k++)
        for (int d = 0; d < 2; d++)
            lo[d] = fmin(lo[d], l->uv[k][d]), hi[d] = fmax(hi[d], l->uv[k][d]);
    double size = n ? hypot(hi[0] - lo[0], hi[1] - lo[1]) : 0;
    if (n < 3 || !(size > 0))
        return sf_fail(g->err, SF_EINVAL, where, "a trim loop encloses no area");
    double gap = hypot(l->uv[l->n - 1][0] - l->uv[loop_start][0], l->uv[l->n - 1][1] - l->uv[loop_start][1]);
    if (gap > LOOP_GAP_REL * size)
        return sf_fail(g->err, SF_EINVAL, where, "a trim loop does not close: its ends are %.3g apart in (u, v), %.2g "
                       "of its size", gap, gap / size);
    if (gap == 0)
        l->n--; /* the first point again */
    if (mem_reserve((void **)&l->counts, &l->cap_loops, l->n_loops + 1, sizeof *l->counts))
        return sf_fail(g->err, SF_ENOMEM, where, "out of memory");
    l->counts[l->n_loops++] = l->n - loop_start;
    return 0;
}

/* Adds the points of curve entity ptr (of owner) to the loop, in parameter or model space; l NULL
 * (trim_budget's count): adds how many it would be to g->n_est. */
static int loop_curve(struct iges *g, struct loops *l, size_t loop_start, int ptr, bool model, bool reverse,
                      const struct on_surface *on, const struct de *owner)
{
    struct de *c = entity(g, ptr, owner, "curve");
    if (!c)
        return SF_EINVAL;
    const double tol = model ? on->tol_mm / g->to_mm : on->tol_uv;
    if (!l)
        return curve_estimate(g, c, tol, 0, &g->n_est);
    struct poly pl = {0};
    int rc = curve_points(g, c, tol, 0, &pl);
    if (!rc)
        rc = loop_add(g, l, loop_start, &pl, model, reverse, on, owner);
    free(pl.p);
    return rc;
}

/* The entity owner's pointer ptr names, which must be of type `type` (what: its name), and its
 * parameters (the caller frees them). */
static int typed_entity(struct iges *g, int ptr, const struct de *owner, int type, const char *what,
                        const struct de **out, struct params *p)
{
    const struct de *e = entity(g, ptr, owner, what);
    if (!e)
        return SF_EINVAL;
    char where[24];
    where_of(e, where);
    if (e->type != type)
        return sf_fail(g->err, SF_EINVAL, where, "entity type %d where a %s (%d) belongs", e->type, what, type);
    *out = e;
    return load_params(g, e, p);
}

/* A 142's loop: its parameter-space curve, else its model-space curve projected (l NULL: counted). */
static int loop_142(struct iges *g, struct loops *l, int ptr, const struct on_surface *on, const struct de *owner)
{
    const struct de *e;
    struct params p;
    int rc = typed_entity(g, ptr, owner, 142, "curve on a surface", &e, &p);
    if (rc)
        return rc;
    char where[24];
    where_of(e, where);
    int bptr = p_int_or(&p, 3, 0), cptr = p_int_or(&p, 4, 0);
    size_t start = l ? l->n : 0;
    double before = g->n_est;
    if (bptr)
        rc = loop_curve(g, l, start, bptr, false, false, on, e);
    else if (cptr)
        rc = loop_curve(g, l, start, cptr, true, false, on, e);
    else
        rc = sf_fail(g->err, SF_EINVAL, where, "a curve on a surface with neither a parameter-space nor a model-space "
                     "curve");
    params_free(&p);
    return rc ? rc : loop_close(g, l, start, before, l ? e : owner);
}

/* A 141's loop: per curve its parameter-space curves, else the model-space curve projected (l NULL:
 * counted). */
static int loop_141(struct iges *g, struct loops *l, int ptr, const struct on_surface *on, const struct de *owner)
{
    const struct de *e;
    struct params p;
    int rc = typed_entity(g, ptr, owner, 141, "boundary", &e, &p);
    if (rc)
        return rc;
    char where[24];
    where_of(e, where);
    int n, at = 5;
    if (!p_int(&p, 4, &n) || n < 1 || n > p.n)
        rc = sf_fail(g->err, SF_EINVAL, where, "boundary: its count of curves is missing or wrong");
    size_t start = l ? l->n : 0;
    double before = g->n_est;
    for (int k = 0; k < n && !rc; k++) {
        int crv, sense, m;
        if (!p_int(&p, at, &crv) || !p_int(&p, at + 1, &sense) || !p_int(&p, at + 2, &m) || m < 0 || m > p.n) {
            rc = sf_fail(g->err, SF_EINVAL, where, "boundary: curve %d's pointer, sense or count is missing", k + 1);
            break;
        }
        bool reverse = sense == 2;
        if (m == 0)
            rc = loop_curve(g, l, start, crv, true, reverse, on, e);
        for (int j = 0; j < m && !rc; j++) {
            int psc;
            if (!p_int(&p, at + 3 + (reverse ? m - 1 - j : j), &psc))
                rc = sf_fail(g->err, SF_EINVAL, where, "boundary: parameter-space curve %d of curve %d is missing", j + 1,
                             k + 1);
            else
                rc = loop_curve(g, l, start, psc, false, reverse, on, e);
        }
        at += 3 + m;
    }
    params_free(&p);
    return rc ? rc : loop_close(g, l, start, before, l ? e : owner);
}

/* The name a 406 (form 15) among the property pointers of p gives, the pointers' block starting at
 * parameter at (NA associativities, then NP properties); else the entity's label. */
static void entity_name(struct iges *g, const struct de *e, const struct params *p, int at, char *name, size_t n)
{
    snprintf(name, n, "%s", e->label);
    int na = p_int_or(p, at, 0), np = na >= 0 ? p_int_or(p, at + 1 + na, 0) : 0;
    for (int k = 0; k < np && k < 64; k++) {
        int ptr = p_int_or(p, at + 2 + na + k, 0);
        if (ptr <= 0 || ptr % 2 == 0 || (ptr - 1) / 2 >= g->n_de)
            continue;
        const struct de *q = &g->de[(ptr - 1) / 2];
        struct params qp;
        if (q->type != 406 || q->form != 15 || load_params(g, q, &qp))
            continue;
        if (qp.n > 2 && qp.f[2].str) /* NP = 1, then the name */
            snprintf(name, n, "%.*s", qp.f[2].str_len, qp.f[2].str);
        params_free(&qp);
        return;
    }
}

/* The rectangle of the U/V ranges as a loop. */
static int loop_rect(struct iges *g, struct loops *l, const double dom[4], const char *where)
{
    const double rect[4][2] = {{dom[0], dom[2]}, {dom[1], dom[2]}, {dom[1], dom[3]}, {dom[0], dom[3]}};
    if (mem_reserve((void **)&l->uv, &l->cap, l->n + 4, sizeof *l->uv) ||
        mem_reserve((void **)&l->counts, &l->cap_loops, l->n_loops + 1, sizeof *l->counts))
        return sf_fail(g->err, SF_ENOMEM, where, "out of memory");
    memcpy(l->uv + l->n, rect, sizeof rect);
    l->n += 4;
    l->counts[l->n_loops++] = 4;
    return 0;
}

/* ---- the scene -------------------------------------------------------------------------- */

static vec3 colour_of(struct iges *g, const struct de *e, vec3 dflt)
{
    static const double STANDARD[9][3] = {{0.8, 0.8, 0.8}, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1},
                                          {1, 1, 0},       {1, 0, 1}, {0, 1, 1}, {1, 1, 1}};
    double c[3] = {dflt.x, dflt.y, dflt.z};
    if (e->color > 0 && e->color <= 8) {
        for (int d = 0; d < 3; d++)
            c[d] = STANDARD[e->color][d];
    } else if (e->color < 0) {
        const struct de *t = entity(g, -e->color, e, "colour");
        struct params p;
        if (!t || t->type != 314 || load_params(g, t, &p))
            return dflt; /* a colour is no reason to refuse a part */
        for (int d = 0; d < 3; d++) {
            double v;
            if (p_num(&p, 1 + d, &v))
                c[d] = pow(fmin(fmax(v / 100.0, 0.0), 1.0), 2.2); /* percent of a display intensity: sRGB-like */
        }
        params_free(&p);
        if (c[0] == 0 && c[1] == 0 && c[2] == 0)
            return dflt; /* Rhino's "no colour": a black part shows nothing but its outline */
    } else {
        return dflt;
    }
    return v3(c[0], c[1], c[2]);
}

static double hull_size(const struct surface *s)
{
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (int k = 0; k < s->n_u * s->n_v; k++)
        for (int d = 0; d < 3; d++)
            lo[d] = fmin(lo[d], s->points[3 * k + d]), hi[d] = fmax(hi[d], s->points[3 * k + d]);
    return hypot(hypot(hi[0] - lo[0], hi[1] - lo[1]), hi[2] - lo[2]);
}

/* What the loops of surface s (its U/V ranges in on->dom) are drawn on. */
static void on_surface_init(struct on_surface *on, const struct surface *s)
{
    on->s = s;
    on->size_mm = hull_size(s);
    on->tol_uv = TRIM_TOL_REL * hypot(on->dom[1] - on->dom[0], on->dom[3] - on->dom[2]);
    on->tol_mm = TRIM_TOL_REL * on->size_mm;
    on->closed[0] = closes(on, 0), on->closed[1] = closes(on, 1);
}

/* The loops that owner (a 143 or 144) gives surface on, appended to l, and its 406's name into
 * name; l NULL (trim_budget's count, name NULL): their points counted into g->n_est instead. whole:
 * the surface's U/V ranges are its knots' (a 144 without an outer loop then needs no rectangle). */
static int owner_loops(struct iges *g, struct loops *l, const struct on_surface *on, bool whole,
                       const struct de *owner, char *name, size_t name_len)
{
    char where[24];
    where_of(owner, where);
    struct params p;
    int rc = load_params(g, owner, &p);
    if (rc)
        return rc;
    if (owner->type == 144) { /* PTS, N1, N2, PTO, PTI(N2) */
        int n1 = p_int_or(&p, 2, 0), n2 = p_int_or(&p, 3, 0);
        if (n2 < 0 || n2 > p.n)
            rc = sf_fail(g->err, SF_EINVAL, where, "trimmed surface: its count of holes is wrong");
        if (!rc && n1 == 0 && (n2 > 0 || !whole)) /* the natural boundary: a loop round the U/V ranges */
            rc = l ? loop_rect(g, l, on->dom, where) : budget_add(g, 4, owner);
        else if (!rc && n1)
            rc = loop_142(g, l, p_int_or(&p, 4, 0), on, owner);
        for (int k = 0; k < n2 && !rc; k++)
            rc = loop_142(g, l, p_int_or(&p, 5 + k, 0), on, owner);
        if (name)
            entity_name(g, owner, &p, 5 + n2, name, name_len);
    } else { /* 143: TYPE, SPTR, N, BDPT(N) */
        int n = p_int_or(&p, 3, 0);
        if (n < 1 || n > p.n)
            rc = sf_fail(g->err, SF_EINVAL, where, "bounded surface: its count of boundaries is missing or wrong");
        for (int k = 0; k < n && !rc; k++)
            rc = loop_141(g, l, p_int_or(&p, 4 + k, 0), on, owner);
        if (name)
            entity_name(g, owner, &p, 4 + n, name, name_len);
    }
    params_free(&p);
    return rc;
}

/* One drawn object: surface sde trimmed as entity owner (a 143 or 144) says, or untrimmed but for
 * its U/V ranges (owner NULL). */
static int add_object(struct iges *g, struct scene *sc, const struct de *sde, const struct de *owner)
{
    struct object *o = scene_add_object(sc);
    char where[24];
    where_of(owner ? owner : sde, where);
    if (!o)
        return sf_fail(g->err, SF_ELIMIT, where, "more than %d surfaces, or out of memory", SCENE_MAX_OBJECTS);
    struct on_surface on;
    int rc = read_surface(g, sde, &o->surf, on.dom);
    if (rc)
        return rc;
    on_surface_init(&on, &o->surf);
    o->mat.color = colour_of(g, owner && owner->color ? owner : sde, o->mat.color);
    o->source = (owner ? owner : sde)->line;
    snprintf(o->name, sizeof o->name, "%s", (owner ? owner : sde)->label);
    double k0, k1, l0, l1;
    nurbs_domain(&o->surf, &k0, &k1, &l0, &l1);
    const bool whole = on.dom[0] == k0 && on.dom[1] == k1 && on.dom[2] == l0 && on.dom[3] == l1;
    struct loops l = {0};
    if (owner)
        rc = owner_loops(g, &l, &on, whole, owner, o->name, sizeof o->name);
    else if (!whole) /* U/V ranges within the knots: the rectangle they span */
        rc = loop_rect(g, &l, on.dom, where);
    int group = (owner ? owner : sde)->group;
    if (!rc && !o->name[0] && group >= 0) /* unnamed: its group's name */
        snprintf(o->name, sizeof o->name, "%s", g->de[group].name);
    /* trim_build polls where the count stands now: the progress never goes back */
    struct sf_span at = {g->pr, g->n_est > 0 ? fmin(1.0, g->n_trim / g->n_est) : 0, 0};
    at.hi = at.lo;
    const struct sf_progress at_pr = {sf_span_poll, &at};
    if (!rc && l.n_loops) {
        o->trim = calloc(1, sizeof *o->trim);
        if (!o->trim)
            rc = sf_fail(g->err, SF_ENOMEM, where, "out of memory");
        else if ((rc = trim_build(o->trim, (const double(*)[2])l.uv, l.counts, (int)l.n_loops, where,
                                  g->pr ? &at_pr : NULL, g->err))) {
            free(o->trim);
            o->trim = NULL;
        }
    }
    loops_free(&l);
    return rc;
}

/* The surface a 143 or 144 bounds (not yet checked to be a 128), or NULL (err set). */
static struct de *bounded_surface(struct iges *g, const struct de *e)
{
    struct params p;
    if (load_params(g, e, &p))
        return NULL;
    struct de *s = entity(g, p_int_or(&p, e->type == 143 ? 2 : 1, 0), e, "surface");
    params_free(&p);
    return s;
}

/* Drawn only through a parent (subordinate switch 01 or 03): a 144's own 128, a loop's curves. */
static bool physically_dependent(const struct de *e) { return e->sub & 1; }

/* Why a file draws nothing, named at its first trimmed surface, else its first surface (each is
 * blanked or physically dependent: the first such one is what was meant to be drawn), or at the
 * Directory when it has none. */
static int nothing_drawn(struct iges *g)
{
    for (int k = 0; k < 2 * g->n_de; k++) { /* 143s and 144s, then 128s */
        const struct de *e = &g->de[k % g->n_de];
        if (k < g->n_de ? e->type != 143 && e->type != 144 : e->type != 128)
            continue;
        char where[24];
        where_of(e, where);
        return sf_fail(g->err, SF_EINVAL, where, "nothing to draw: entity %d, the file's first surface, is %s, as is "
                       "every other (a 128, 143 or 144 is drawn when neither blanked nor physically dependent, "
                       "subordinate switch 01 or 03, which is drawn through a parent only)", e->type,
                       e->blank ? "blanked" : "physically dependent with no parent drawing it");
    }
    return sf_fail(g->err, SF_EINVAL, "D1", "nothing to draw: the file has no surface (128, 143 or 144)");
}

/* 402 groups (forms 1, 7, 14, 15: N members, then their pointers), as CAD systems gather a body's
 * faces: each member remembers its first group, whose name (a 406 name, else its label, read once
 * here) a member drawn without a name of its own takes. Members are drawn as their own status says
 * (a group's are logically dependent, 02, as independent ones are). A group only names: a member
 * pointer to nothing is left out, and a group whose count is wrong names nothing. */
static int read_groups(struct iges *g)
{
    for (int k = 0; k < g->n_de; k++) {
        struct de *e = &g->de[k];
        if (e->type != 402 || (e->form != 1 && e->form != 7 && e->form != 14 && e->form != 15))
            continue;
        struct params p;
        if (load_params(g, e, &p))
            return SF_EINVAL;
        int n = p_int_or(&p, 1, -1);
        if (n >= 0 && n <= p.n - 2) {
            entity_name(g, e, &p, 2 + n, e->name, sizeof e->name);
            for (int m = 0; m < n; m++) {
                int ptr = p_int_or(&p, 2 + m, 0);
                struct de *member = ptr > 0 && ptr % 2 && (ptr - 1) / 2 < g->n_de ? &g->de[(ptr - 1) / 2] : NULL;
                if (member && member->group < 0)
                    member->group = k;
            }
        }
        params_free(&p);
    }
    return 0;
}

/* Counts, before any loop is made, the points the loops of every surface scene_parse_iges draws
 * will take (g->n_est) and refuses the part (SF_ELIMIT) at the surface where the count passes
 * IGES_MAX_TRIM_POINTS. Each bounded surface is read once here for its tolerances. */
static int trim_budget(struct iges *g)
{
    int rc = 0;
    for (int k = 0; k < g->n_de && !rc; k++) {
        const struct de *e = &g->de[k];
        if (e->blank || physically_dependent(e))
            continue;
        if (e->type == 128 && !e->bounded) { /* at most the rectangle of its U/V ranges */
            rc = budget_add(g, 4, e);
            continue;
        }
        if (e->type != 143 && e->type != 144)
            continue;
        struct de *s = bounded_surface(g, e);
        if (!s) {
            rc = SF_EINVAL;
            break;
        }
        struct on_surface on = {0};
        if (!s->tols_known) {
            struct surface surf;
            if ((rc = read_surface(g, s, &surf, on.dom)))
                break;
            on_surface_init(&on, &surf);
            s->tol_uv = on.tol_uv, s->tol_mm = on.tol_mm, s->tols_known = true;
            nurbs_surface_free(&surf);
        }
        on = (struct on_surface){.tol_uv = s->tol_uv, .tol_mm = s->tol_mm};
        if (!(rc = owner_loops(g, NULL, &on, false, e, NULL, 0)))
            rc = sf_poll(g->pr, 0, g->err);
    }
    return rc;
}

/* Millimetres per unit of the Global section's unit flag (and, for flag 3, its name). */
static double unit_mm(int flag, const char *name, int name_len)
{
    static const double MM[12] = {0, 25.4, 1, 0, 304.8, 1609344, 1000, 1e6, 0.0254, 0.001, 10, 2.54e-5};
    if (flag >= 1 && flag <= 11 && flag != 3)
        return MM[flag];
    static const struct {
        const char *name;
        double mm;
    } NAMES[] = {{"IN", 25.4}, {"INCH", 25.4}, {"MM", 1}, {"FT", 304.8}, {"MI", 1609344}, {"M", 1000},
                 {"KM", 1e6},  {"MIL", 0.0254}, {"UM", 0.001}, {"CM", 10}, {"UIN", 2.54e-5}};
    for (size_t k = 0; name && k < sizeof NAMES / sizeof *NAMES; k++)
        if ((int)strlen(NAMES[k].name) == name_len && !strncasecmp(NAMES[k].name, name, (size_t)name_len))
            return NAMES[k].mm;
    return 0;
}

/* The Global section: delimiters (fields 1, 2) and the unit (13 scale is left alone, as by other
 * readers; 14 flag, 15 name). Takes text (frees it). */
static int read_global(struct iges *g, char *text, size_t len)
{
    size_t k = 0;
    char d[2] = {',', ';'};
    for (int f = 0; f < 2; f++) { /* each "1Hc" or empty, then the parameter delimiter */
        if (k + 3 <= len && text[k] == '1' && (text[k + 1] == 'H' || text[k + 1] == 'h')) {
            d[f] = text[k + 2];
            k += 3;
        }
        if (f == 0 && k < len && text[k] != d[0] && d[0] != ',') {
            free(text);
            return sf_fail(g->err, SF_EFORMAT, "G1", "the Global section's first field is not a delimiter");
        }
        if (k < len && (text[k] == d[0] || text[k] == d[1]))
            k++;
    }
    g->pd = d[0], g->rd = d[1];
    if (g->pd == g->rd || isdigit((unsigned char)g->pd) || g->pd == ' ' || g->rd == ' ') {
        free(text);
        return sf_fail(g->err, SF_EFORMAT, "G1", "the Global section's delimiters are not usable");
    }
    struct params p = {0};
    int rc = split_fields(&p, text, len, g->pd, g->rd, "G1", g->err); /* takes text */
    if (rc) {
        params_free(&p);
        return rc;
    }
    /* fields count from 1 in the standard: field f is p.f[f - 1] */
    int flag = p_int_or(&p, 13, 1);
    g->to_mm = unit_mm(flag, 14 < p.n ? p.f[14].str : NULL, 14 < p.n ? p.f[14].str_len : 0);
    params_free(&p);
    if (!(g->to_mm > 0))
        return sf_fail(g->err, SF_EINVAL, "G14", "unit flag %d (and its name) names no unit", flag);
    return 0;
}

int scene_parse_iges(const char *buf, size_t len, struct scene *sc, struct sf_err *err)
{
    return iges_parse(buf, len, NULL, sc, err);
}

int iges_parse(const char *buf, size_t len, const struct sf_progress *pr, struct scene *sc, struct sf_err *err)
{
    scene_init(sc);
    struct iges g = {0};
    g.err = err;
    g.pr = pr;
    /* the lines by section */
    struct line *lines = NULL;
    size_t n_lines = 0, cap = 0;
    int rc = 0;
    char where[32];
    for (size_t at = 0, no = 1; at < len && !rc; no++) {
        const char *e = memchr(buf + at, '\n', len - at);
        size_t end = e ? (size_t)(e - buf) : len, n = end - at;
        if (n && buf[at + n - 1] == '\r')
            n--;
        snprintf(where, sizeof where, "line %zu", no);
        bool blank = true;
        for (size_t k = 0; k < n && blank; k++)
            blank = isspace((unsigned char)buf[at + k]);
        if (!blank && n < 73)
            rc = sf_fail(err, SF_EFORMAT, where, "not an IGES line: %zu columns, where 80 carry the section in column 73",
                         n);
        else if (!blank && !strchr("SGDPT", buf[at + 72]))
            rc = sf_fail(err, SF_EFORMAT, where, "column 73 holds '%c', not a section letter (S, G, D, P, T)%s",
                         buf[at + 72], buf[at + 72] == 'C' || buf[at + 72] == 'B' ? ": compressed and binary IGES are "
                                                                                    "not read" : "");
        else if (!blank && n_lines && strchr("SGDPT", lines[n_lines - 1].section) >
                                          strchr("SGDPT", buf[at + 72]))
            rc = sf_fail(err, SF_EFORMAT, where, "section %c after section %c", buf[at + 72], lines[n_lines - 1].section);
        else if (!blank && mem_reserve((void **)&lines, &cap, n_lines + 1, sizeof *lines))
            rc = sf_fail(err, SF_ENOMEM, "", "out of memory");
        else if (!blank)
            lines[n_lines++] = (struct line){buf + at, buf[at + 72]};
        at = end + 1;
    }
    size_t first[6] = {0}; /* first line of S, G, D, P, T, and the end */
    for (int s = 0; s < 5; s++) {
        size_t k = first[s];
        while (k < n_lines && lines[k].section == "SGDPT"[s])
            k++;
        first[s + 1] = k;
    }
    for (int s = 1; s < 4 && !rc; s++) /* Global, Directory, Parameter: each named by its letter when missing */
        if (first[s + 1] == first[s]) {
            const char section[2] = {"SGDPT"[s], 0};
            rc = sf_fail(err, SF_EFORMAT, section, "not an IGES file: it has no %s section (column 73 '%s')",
                         s == 1 ? "Global" : s == 2 ? "Directory" : "Parameter", section);
        }
    /* Global */
    if (!rc) {
        size_t n = first[2] - first[1];
        char *text = malloc(72 * n + 1);
        if (!text)
            rc = sf_fail(err, SF_ENOMEM, "", "out of memory");
        for (size_t k = 0; text && k < n; k++)
            memcpy(text + 72 * k, lines[first[1] + k].s, 72);
        if (text)
            rc = read_global(&g, text, 72 * n);
    }
    /* Directory */
    size_t n_d = first[3] - first[2];
    snprintf(where, sizeof where, "D%zu", n_d % 2 ? n_d : 2 * (size_t)IGES_MAX_ENTITIES + 1);
    if (!rc && n_d % 2)
        rc = sf_fail(err, SF_EFORMAT, where, "the Directory has %zu lines: entries are pairs, and its last is alone",
                     n_d);
    if (!rc && n_d / 2 > IGES_MAX_ENTITIES)
        rc = sf_fail(err, SF_ELIMIT, where, "%zu entities, over the limit of %d", n_d / 2, IGES_MAX_ENTITIES);
    if (!rc && !(g.de = calloc(n_d / 2, sizeof *g.de)))
        rc = sf_fail(err, SF_ENOMEM, "", "out of memory");
    g.n_de = (int)(n_d / 2);
    for (int k = 0; k < g.n_de && !rc; k++) {
        const char *a = lines[first[2] + 2 * (size_t)k].s, *b = lines[first[2] + 2 * (size_t)k + 1].s;
        struct de *e = &g.de[k];
        int type2 = 0, status = 0;
        e->line = 2 * k + 1;
        e->group = -1;
        snprintf(where, sizeof where, "D%d", e->line);
        if (field8(a, 0, &e->type) || field8(a, 1, &e->param) || field8(a, 6, &e->transform) ||
            field8(a, 8, &status) || field8(b, 0, &type2) || field8(b, 2, &e->color) || field8(b, 3, &e->n_lines) ||
            field8(b, 4, &e->form))
            rc = sf_fail(err, SF_EFORMAT, where, "a directory field is not a number");
        else if (type2 != e->type)
            rc = sf_fail(err, SF_EFORMAT, where, "the entry's two lines give entity types %d and %d", e->type, type2);
        e->blank = status / 1000000;
        e->sub = status / 10000 % 100;
        size_t lb = 0, le = 8;
        while (lb < 8 && b[56 + lb] == ' ')
            lb++;
        while (le > lb && b[56 + le - 1] == ' ')
            le--;
        memcpy(e->label, b + 56 + lb, le - lb);
        e->label[le - lb] = 0;
    }
    /* Parameter data */
    size_t n_p = first[4] - first[3];
    if (!rc && !(g.p_line = malloc(sizeof *g.p_line * n_p)))
        rc = sf_fail(err, SF_ENOMEM, "", "out of memory");
    for (size_t k = 0; !rc && k < n_p; k++)
        g.p_line[k] = lines[first[3] + k].s;
    g.n_p = (int)n_p;
    /* the surfaces that 143s and 144s bound are drawn only so */
    for (int k = 0; k < g.n_de && !rc; k++) {
        struct de *e = &g.de[k];
        if (e->type != 143 && e->type != 144)
            continue;
        struct de *s = bounded_surface(&g, e);
        if (s)
            s->bounded = true;
        else
            rc = SF_EINVAL;
    }
    if (!rc)
        rc = read_groups(&g);
    if (!rc)
        rc = trim_budget(&g);
    for (int k = 0; k < g.n_de && !rc; k++) {
        struct de *e = &g.de[k];
        if (e->blank || physically_dependent(e))
            continue;
        if (e->type == 128 && !e->bounded)
            rc = add_object(&g, sc, e, NULL);
        else if (e->type == 143 || e->type == 144) {
            const struct de *s = bounded_surface(&g, e);
            rc = s ? add_object(&g, sc, s, e) : SF_EINVAL;
        }
        if (!rc && (e->type == 128 || e->type == 143 || e->type == 144))
            rc = poll_cancel(&g, 0);
    }
    if (!rc && sc->n_objects == 0)
        rc = nothing_drawn(&g);
    free(lines);
    free(g.de);
    free(g.p_line);
    if (rc)
        scene_free(sc);
    return rc ? (err && err->code ? err->code : rc) : 0;
}
