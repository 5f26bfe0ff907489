/* dicom_scan.h - one linear pass over a DICOM object's structure (a slice of a series, an RT
 * Structure Set) before DCMTK reads it, refusing what would make DCMTK's reader fail badly:
 * a declared length past what is left (DCMTK allocates it first), sequences nested deep enough
 * to overflow its recursive reader's stack, and element counts, orders and private creators
 * that make its element lists quadratic. Plain C, no DCMTK: it sees only the bytes. */
#ifndef SURFD_DICOM_SCAN_H
#define SURFD_DICOM_SCAN_H

#include <stdbool.h>
#include <stddef.h>

#ifdef __cplusplus
extern "C" { /* the C header below declares C functions */
#endif

#include "../core/base/err.h"

/* Sequences inside sequences (an item's data set counts with its sequence). Real objects nest
 * under 10 deep (an RT Structure Set's ContourImageSequence is the 3rd, an enhanced image's
 * functional groups the 3rd or 4th); DCMTK recurses some kilobytes of stack a level, and
 * 10 000 levels overflowed an 8 MB thread. 16 keeps every real object with room to spare. */
#define DICOM_MAX_DEPTH 16
/* Elements, items and fragments in one object. The largest real RT Structure Sets hold some
 * hundreds of thousands; DCMTK spends about 230 bytes and a microsecond on each, so the cap
 * bounds a part (2 M empty elements are 16 MB of request) at about 460 MB and 2.3 s a read. */
#define DICOM_MAX_ELEMENTS 2000000
/* Elements whose tag is below the greatest already read in their data set or item. DCMTK inserts
 * each element by walking back from its list's end, so each such element costs a walk over the
 * data set (100 000 elements in descending order took 30 s a read); PS3.5 7.1 wants ascending order,
 * and the few files written carelessly (an element appended at the end) keep being read. */
#define DICOM_MAX_DISORDER 16
/* Private creators ((gggg,0010)-(gggg,00FF), gggg odd) in one data set or item. DCMTK looks
 * every private element's creator up in a list of them, so creators x private elements is its
 * cost (80 000 of each took 14 s a read); real objects carry a few dozen at most. */
#define DICOM_MAX_CREATORS 64

struct dicom_scan_stats {
    size_t n_elements;       /* elements, items and fragments read */
    int max_depth;           /* deepest sequence nesting seen */
    int n_disorder;          /* elements below their data set's greatest tag so far */
    int implicit;            /* the data set is implicit VR */
    int big_endian;          /* ... big endian */
    char transfer_syntax[65];/* the meta header's TransferSyntaxUID; "" without a meta header (the
                              * encoding above is then guessed from the first element) */
};

/* Whether data looks like DICOM: "DICM" after a 128-byte preamble, or, for a file without one (as
 * PS3.10 allows and some exports write), a first element of group 0002 or 0008 in little-endian
 * order whose VR is two capital letters (explicit VR) or whose length lies within the data
 * (implicit). What it is is then dicom_scan's to say. */
bool dicom_sniff(const void *data, size_t len);

/* 0 when DCMTK may read data (len bytes: a Part 10 file, with its preamble, "DICM" and meta
 * header, or a bare data set) in the encoding stats says (dcmtk_in.h reads it so, never in
 * DCMTK's own guess); else SF_EFORMAT (a length past its container, an item where none belongs,
 * an unknown VR, elements out of order past DICOM_MAX_DISORDER, a meta header without its
 * transfer syntax), SF_EINVAL (a deflated or non-standard transfer syntax) or SF_ELIMIT (depth,
 * elements, creators), with pointer as err's pointer and a message naming the element and its
 * byte offset. stats may be NULL. */
int dicom_scan(const void *data, size_t len, const char *pointer, struct dicom_scan_stats *stats, struct sf_err *err);

/* The same pass, blanking in place the values of the elements that identify the patient (PS3.15's
 * basic profile, keeping UIDs; and every private element), at any depth: each value keeps its
 * length, so the object's layout (and a multipart body around it) is unchanged, and DCMTK reads
 * the same structure with empty values. *n_blanked: the values blanked. Errors as dicom_scan. */
int dicom_blank_identity(void *data, size_t len, const char *pointer, size_t *n_blanked, struct sf_err *err);

#ifdef __cplusplus
}
#endif

#endif
