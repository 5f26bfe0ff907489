/* nifti.h - the header of a NIfTI-1 or NIfTI-2 single file (.nii; its gzip, .nii.gz, is inflated
 * by volume_io.c): the grid's sizes, its samples' type, scaling and place in the file, and the
 * voxel-to-world affine (sform, else qform, else the pixdims alone) in mm.
 *
 * Written by hand: the format is one fixed header of documented offsets, and the reference library
 * (nifticlib) is not packaged for Debian as a library C programs link; nibabel is Python. What the
 * affine means is nifti1.h's (the NIfTI-1 standard's comments): world coordinates are RAS+. */
#ifndef SURFD_NIFTI_H
#define SURFD_NIFTI_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "../core/base/err.h"

/* Bytes of the header that decide everything (NIfTI-2's; NIfTI-1's is 348). */
#define NIFTI_HEADER_MAX 540
/* Bytes of header extensions a file may hold between its header and its samples (what a gzip
 * file makes surfd inflate beyond its samples). */
#define NIFTI_MAX_EXTENSIONS (16 << 20)

struct nifti_header {
    int version;             /* 1 or 2 */
    int64_t dims[3];         /* the 4th and later sizes are 1 (one volume) */
    int datatype;            /* NIfTI's code: 2 uint8, 4 int16, 8 int32, 16 float32, 64 float64, 256 int8,
                              * 512 uint16, 768 uint32 */
    int bytes;               /* of one sample */
    bool big_endian;
    int64_t vox_offset;      /* where the samples begin */
    double slope, inter;     /* a sample's value is slope * stored + inter (slope 0: none; a file's NaN or 0 is none) */
    double affine[3][4];     /* voxel (i, j, k) to world RAS+ in mm: x = affine[0] . (i, j, k, 1) */
    const char *xform;       /* what gave the affine: "sform", "qform" or "pixdim" */
    char intent_name[17];    /* what the file calls its samples ("" when nothing) */
};

/* Whether buf begins as a NIfTI-1 or NIfTI-2 header (either byte order), single file or pair. */
bool nifti_sniff(const unsigned char *buf, size_t len);
/* The first bytes of a gzip (or zlib) stream, up to cap, into out (*got of them: fewer when the
 * stream is shorter): 0, or SF_EFORMAT (at "header") when it does not inflate. err may be NULL. */
int nifti_inflate_head(const char *src, size_t n, unsigned char *out, size_t cap, size_t *got, struct sf_err *err);
/* Whether a body is a NIfTI file: its header, or the gzip of one (.nii.gz). */
bool nifti_sniff_body(const char *body, size_t len);
/* Reads the header at buf (len >= NIFTI_HEADER_MAX or the whole file): 0, or SF_EFORMAT (not a
 * NIfTI header), SF_EINVAL (a header of a file surfd does not read: a pair, 4-D, a datatype it has
 * no samples for, an affine that is not a grid's), with the field named in the message and
 * "header" as the pointer. */
int nifti_header(const unsigned char *buf, size_t len, struct nifti_header *h, struct sf_err *err);

/* The label table of a file's header extensions (file: its first len bytes, h its header): each
 * <Label Key="N">name</Label> of an extension's XML, as GIFTI's and CIFTI's label tables write
 * them (the name as text or CDATA, XML's five entities read), to fn(ctx, N, name, its length);
 * extensions that run past vox_offset or the file end the search. The number of labels found. */
int nifti_label_table(const unsigned char *file, size_t len, const struct nifti_header *h,
                      void (*fn)(void *ctx, long long value, const char *name, size_t n), void *ctx);

#endif
