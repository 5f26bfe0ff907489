/* seg.h - a DICOM Segmentation (PS3.3 A.51), BINARY, through DCMTK's dcmdata behind seg_dcmtk.cpp:
 * segments (a label, a colour, an interpreted type) over one grid of slices, a frame per segment
 * per slice where the segment is not empty, each referencing its slice's source image when the
 * grid is a stored series'. Writes no patient data: the patient's and study's type 2 elements are
 * present and empty. What is in a frame is the caller's (model_seg.c voxelises models). */
#ifndef SURFD_SEG_H
#define SURFD_SEG_H

#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

#include "../core/base/err.h"

/* The bits of one export: slices x rows x columns x segments, held to this before a voxel is made
 * (and so before any frame or the object is allocated): 2^31 bits is 256 MB of packed frames, 20
 * segments on a 512 x 512 x 300 CT fit (1.6e9) */
#define SEG_MAX_BITS (1ULL << 31)
/* frames of one export (slices x segments at most): frames_dcmtk.cpp reads no more, and what surfd
 * writes it reads back */
#define SEG_MAX_FRAMES (1L << 18)

struct seg_image {           /* a slice's source image: DerivationImageSequence, ReferencedSeriesSequence */
    char sop_class[65], sop_instance[65];
};

/* A grid of slices, as a series' images lie: each slice Rows x Columns pixels of PixelSpacing,
 * placed by its ImagePositionPatient, all of one ImageOrientationPatient. */
struct seg_grid {
    int cols, rows, n_slices;
    double spacing[2];       /* PixelSpacing: between rows, between columns (mm) */
    double orient[6];        /* ImageOrientationPatient: the row direction, then the column one */
    double (*pos)[3];        /* n_slices positions (malloc'ed), ascending along the normal, row x column */
    double thickness;        /* the slices' spacing (mm): PixelMeasures' SliceThickness */
    struct seg_image *images;/* n_slices source images (malloc'ed), or NULL: none referenced */
    char series_uid[65];     /* the images' series, "" without images */
    char study_uid[65];      /* the series' study ("": the models') */
    char frame_uid[65];      /* the series' frame of reference ("": the models') */
    const char *source;      /* where the grid came from, for the answer: "series", "model" or "spacing" */
};
/* Frees g's arrays; g itself is the caller's. A zeroed grid is freed as a no-op. */
void seg_grid_free(struct seg_grid *g);

struct seg_segment {
    const char *label;       /* SegmentLabel: the model's name (printable, cut to 64 characters) */
    int color[3];            /* sRGB 0..255, written as RecommendedDisplayCIELabValue (PS3.3 C.10.7.1.1) */
    const char *type;        /* RTROIInterpretedType (ORGAN, PTV ...): SegmentDescription */
};

struct seg_writer;
/* Starts a Segmentation of n segments (numbered 1..n in s's order) on grid g, in study study_uid
 * and frame of reference frame_uid (NULL or "": fresh UIDs). g and s are borrowed until seg_end.
 * 0, SF_ELIMIT (over SEG_MAX_BITS or 65535 segments), SF_ENOMEM. */
int seg_begin(const struct seg_grid *g, const struct seg_segment *s, int n, const char *study_uid,
              const char *frame_uid, struct seg_writer **out, struct sf_err *err);
/* Adds segment's (1..n) frame at slice (0..n_slices - 1): mask is Rows x Columns bytes, row after
 * row, non-zero inside. Frames come in any order; the object lists them as added. 0, SF_ENOMEM. */
int seg_frame(struct seg_writer *w, int segment, int slice, const unsigned char *mask, struct sf_err *err);
/* The object: *out (caller frees), *out_len; frees w either way. 0, SF_EINVAL (no frame: every
 * segment empty on the grid), SF_ENOMEM, SF_EBACKEND. */
int seg_end(struct seg_writer *w, unsigned char **out, size_t *out_len, struct sf_err *err);
/* Frees a writer not ended (after a failure). NULL: a no-op. */
void seg_free(struct seg_writer *w);

/* sRGB (0..255 each) as PS3.3 C.10.7.1.1's scaled CIELab (D65): L 0..100 and a, b -128..127 to 0..65535. */
void seg_cielab(const int rgb[3], unsigned lab[3]);

#ifdef __cplusplus
}
#endif

#endif
