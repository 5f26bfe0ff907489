/* fuzz_frames.c - one multi-frame DICOM image (an Enhanced CT/MR, an RT Dose, a Segmentation:
 * api/frames_dcmtk.cpp through dicom_series.h) read as POST /isosurface reads a single DICOM
 * body: its headers alone first (the upload's check), then whole, for no segment and for
 * segments 1 and 2, each as it is and as a label map (?labels=all, ?label=N). What reads whole must have passed the check with the same grid (its size,
 * spacing, origin and axes, and its type where the check says it: the check says every size and
 * place before anything is decoded), lie within the cap, and hold finite samples; a small one is
 * polygonised, and its mesh must be closed and consistently oriented. */
#include <math.h>
#include <string.h>

#include "../../api/dicom_series.h"
#include "../../core/iso/mc.h"
#include "fuzz.h"

#define FRAMES_FUZZ_MAX_SAMPLES (1u << 22) /* a cap of its own, so that the fuzzer meets it */
#define EXTRACT_MAX_SAMPLES 40000

/* Whether the check's grid is the one read whole: the same doubles, not near ones (both come of
 * one layout of the same planes). */
static bool same_place(const struct series *a, const struct series *b)
{
    return a->g.nx == b->g.nx && a->g.ny == b->g.ny && a->g.nz == b->g.nz &&
           !memcmp(a->g.spacing, b->g.spacing, sizeof a->g.spacing) &&
           !memcmp(a->g.origin, b->g.origin, sizeof a->g.origin) && !memcmp(a->axes, b->axes, sizeof a->axes);
}

static void read_as(const struct part *p, int segment, bool labels)
{
    struct series chk, s;
    struct sf_err e1 = {0}, e2 = {0};
    int rc_chk = series_read(p, 1, true, FRAMES_FUZZ_MAX_SAMPLES, segment, labels, &chk, &e1);
    free(chk.owned);
    free(chk.segments);
    if (rc_chk == SF_ENOMEM) /* (the torture build refused one of the check's allocations) */
        return;
    if (series_read(p, 1, false, FRAMES_FUZZ_MAX_SAMPLES, segment, labels, &s, &e2))
        return;
    size_t n = (size_t)s.g.nx * s.g.ny * s.g.nz;
    if (rc_chk || !same_place(&chk, &s) || n > FRAMES_FUZZ_MAX_SAMPLES || !s.owned ||
        (chk.typed && chk.g.type != s.g.type) || chk.label_map != s.label_map || chk.n_segments != s.n_segments)
        abort(); /* read whole past what its check said, elsewhere than it said, or past the cap */
    for (size_t i = 0; s.label_map && i < n; i++) { /* a label map holds only the segments it names */
        unsigned v = ((const uint16_t *)s.owned)[i];
        bool named = v == 0;
        for (int k = 0; k < s.n_segments && !named; k++)
            named = s.segments[k].number == v;
        if (!named)
            abort();
    }
    free(s.segments);
    if (s.g.type == ISO_F32)
        for (size_t i = 0; i < n; i++)
            if (!isfinite(((const float *)s.owned)[i]))
                abort();
    if (n <= EXTRACT_MAX_SAMPLES) {
        struct iso_opts o = {.iso = s.g.type == ISO_U8 || s.label_map ? 0.5 : 1.0, .closed = true, .normals = true};
        struct trimesh m;
        struct trimesh_stats st;
        struct sf_err e3 = {0};
        if (iso_extract(&s.g, &o, NULL, &m, &e3) == 0 && trimesh_stats(&m, &st, &e3) == 0 &&
            (st.boundary_edges || st.nonmanifold_edges || st.degenerate))
            abort();
        trimesh_free(&m);
    }
    free(s.owned);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static bool tables;
    if (!tables) {
        iso_init();
        tables = true;
    }
    struct part p = {(const char *)data, size, NULL, 0};
    for (int segment = 0; segment <= 2; segment++)
        for (int labels = 0; labels <= 1; labels++)
            read_as(&p, segment, labels);
    return 0;
}
