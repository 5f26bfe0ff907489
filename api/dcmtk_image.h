// dcmtk_image.h - what the DCMTK shims that read images to a grid share (series_dcmtk.cpp: a
// series, one image a part; frames_dcmtk.cpp: one multi-frame image): the ranges a plane's
// geometry and rescale keep, reading them, the codecs, decoding one frame's pixel data in place and
// a stored sample's value. C++, for those shims alone; inline, so that neither calls the other's
// object for it.
#ifndef SURFD_DCMTK_IMAGE_H
#define SURFD_DCMTK_IMAGE_H

#include <dcmtk/config/osconfig.h>
#include <dcmtk/dcmdata/dcpixseq.h>
#include <dcmtk/dcmdata/dcpxitem.h>
#include <dcmtk/dcmdata/dcrledrg.h>
#include <dcmtk/dcmdata/dctk.h>
#include <dcmtk/dcmjpeg/djdecode.h>
#include <dcmtk/dcmjpls/djdecode.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <mutex>
#include <vector>

#include "dicom_series.h"
#include "j2k.h"
#include "ranges.h"

/* The ranges a plane's geometry and rescale must keep, so that every product the grid and the
 * mesh make of them (positions over spacings, samples times slopes) stays finite in float, and
 * a volume comes out of real numbers: positions within RANGE_MAX_COORD, PixelSpacing and the
 * spacing between planes within [RANGE_MIN_SPACING, RANGE_MAX_SPACING] (ranges.h, as every
 * volume's); a 32-bit sample times 1e6 plus 1e9 is well inside float. */
#define SERIES_MAX_SLOPE 1e6     /* |RescaleSlope|, DoseGridScaling */
#define SERIES_MAX_INTERCEPT 1e9 /* |RescaleIntercept| */
#define ORIENT_EPS 1e-3          /* how far past 1 a direction cosine may round */

enum { GOT, MISSING, NOT_FINITE };

/* The first n values of tag in item: GOT, MISSING (absent or fewer than n) or NOT_FINITE. */
static inline int get_doubles(DcmItem *item, const DcmTagKey &tag, double *out, unsigned n)
{
    for (unsigned k = 0; k < n; k++) {
        Float64 v;
        if (!item || item->findAndGetFloat64(tag, v, k).bad())
            return MISSING;
        if (!std::isfinite(v))
            return NOT_FINITE;
        out[k] = v;
    }
    return GOT;
}

/* 0 when each of the n values of name (read as got says) is within [lo, hi] in magnitude; else
 * SF_EINVAL at where naming the element and its values. missing_ok: an absent element keeps the
 * default. */
static inline int check_range(struct sf_err *err, const char *where, const char *name, int got, const double *v,
                              unsigned n, double lo, double hi, bool missing_ok)
{
    char what[240];
    if (got == MISSING && missing_ok)
        return 0;
    if (got == MISSING)
        return sf_fail(err, SF_EINVAL, where, "%s is missing or has fewer than %u values", name, n);
    if (got == NOT_FINITE)
        return sf_fail(err, SF_EINVAL, where, "%s holds a value that is not a finite number", name);
    for (unsigned k = 0; k < n; k++)
        if (!(std::fabs(v[k]) >= lo && std::fabs(v[k]) <= hi)) {
            if (lo > 0)
                snprintf(what, sizeof what, "%s value %u is %.6g: surfd reads %g to %g in magnitude", name, k + 1,
                         v[k], lo, hi);
            else
                snprintf(what, sizeof what, "%s value %u is %.6g: surfd reads at most %g in magnitude", name, k + 1,
                         v[k], hi);
            return sf_fail(err, SF_EINVAL, where, "%s", what);
        }
    return 0;
}

/* The items of seq, walked once. DCMTK's getItem(i) walks its list from the start on every call,
 * so a loop over i is quadratic in the count, which the object sets: 262 144 per-frame items took
 * 164 s that way. T: DcmItem, or DcmPixelItem for a pixel sequence's fragments. */
template <class T> std::vector<T *> items_of(DcmSequenceOfItems *seq)
{
    std::vector<T *> out;
    if (!seq)
        return out;
    out.reserve(seq->card());
    for (DcmObject *o = seq->nextInContainer(nullptr); o; o = seq->nextInContainer(o))
        out.push_back(OFstatic_cast(T *, o));
    return out;
}

/* The decoders, registered once a process (DCMTK's registries are global). */
static inline void register_codecs()
{
    static std::once_flag once;
    std::call_once(once, [] {
        DcmRLEDecoderRegistration::registerCodecs();
        DJDecoderRegistration::registerCodecs();
        DJLSDecoderRegistration::registerCodecs();
    });
}

/* Whether a compressed transfer syntax is one those decoders take, or JPEG 2000 (j2k.h: OpenJPEG). */
static inline bool decodable(E_TransferSyntax t)
{
    if (j2k_syntax(DcmXfer(t).getXferID()))
        return true;
    switch (t) {
    case EXS_RLELossless:
    case EXS_JPEGProcess1:
    case EXS_JPEGProcess2_4:
    case EXS_JPEGProcess14:
    case EXS_JPEGProcess14SV1:
    case EXS_JPEGLSLossless:
    case EXS_JPEGLSLossy:
        return true;
    default:
        return false;
    }
}

/* The image pixel module's elements (PS3.3 C.7.6.3) that size a frame, and how they are coded. */
struct pixel_module {
    unsigned rows = 0, cols = 0, bits = 0, stored = 0; /* stored: BitsStored, all of bits when 0 or more */
    bool is_signed = false;
    E_TransferSyntax xfer = EXS_Unknown;
    bool encapsulated = false;
};

/* ds's pixel module into h, refused alike for a series' slice and a multi-frame image (SF_EINVAL
 * or SF_ELIMIT at where): compressed in a syntax no decoder here takes, no Rows or Columns,
 * SamplesPerPixel other than 1, a frame of 2 GB or more. What BitsAllocated may be is the
 * caller's to say (a CT's 8 or 16, an RT Dose's 16 or 32, a Segmentation's 1 or 8). */
static inline int read_pixel_module(DcmDataset *ds, const char *where, pixel_module &h, struct sf_err *err)
{
    h.xfer = ds->getOriginalXfer();
    DcmXfer x(h.xfer);
    h.encapsulated = x.isEncapsulated();
    if (h.encapsulated && !decodable(h.xfer))
        return sf_fail(err, SF_EINVAL, where, "compressed pixel data (%s) is not read: send it uncompressed, or as RLE, "
                       "JPEG (baseline, extended, lossless), JPEG-LS or JPEG 2000", x.getXferName());
    Uint16 rows = 0, cols = 0, bits = 0, stored = 0, rep = 0, spp = 1;
    if (ds->findAndGetUint16(DCM_Rows, rows).bad() || ds->findAndGetUint16(DCM_Columns, cols).bad() || rows < 1 ||
        cols < 1)
        return sf_fail(err, SF_EINVAL, where, "an image without Rows and Columns (is it an image?)");
    ds->findAndGetUint16(DCM_BitsAllocated, bits);
    ds->findAndGetUint16(DCM_BitsStored, stored);
    ds->findAndGetUint16(DCM_PixelRepresentation, rep);
    ds->findAndGetUint16(DCM_SamplesPerPixel, spp);
    if (spp != 1)
        return sf_fail(err, SF_EINVAL, where, "samples are one channel (SamplesPerPixel 1): SamplesPerPixel is %u",
                       (unsigned)spp);
    if ((uint64_t)rows * cols * (bits / 8) >= (1ull << 31))
        return sf_fail(err, SF_ELIMIT, where, "a frame of 2 GB or more (Rows x Columns x BitsAllocated)");
    h.rows = rows, h.cols = cols, h.bits = bits, h.stored = stored && stored <= bits ? stored : bits;
    h.is_signed = rep == 1;
    return 0;
}

/* One frame's compressed pixel data (ds: a data set of one frame, NumberOfFrames absent or 1, so
 * that DCMTK 3.6.7's decoders size their buffer as that frame alone: upstream 31ff413f9) decoded in
 * place to Explicit VR Little Endian. The decoder writes what the stream held: samples of another
 * width than bits are refused, a narrower precision taken into *stored. 0, or SF_EINVAL at where. */
static inline int decode_j2k(DcmDataset *ds, E_TransferSyntax xfer, unsigned bits, unsigned stored, bool is_signed,
                             const char *where, struct sf_err *err);

static inline int decode_frame(DcmDataset *ds, E_TransferSyntax xfer, unsigned bits, unsigned *stored, bool is_signed,
                               const char *where, struct sf_err *err)
{
    if (j2k_syntax(DcmXfer(xfer).getXferID()))
        return decode_j2k(ds, xfer, bits, *stored, is_signed, where, err);
    register_codecs();
    OFCondition c = ds->chooseRepresentation(EXS_LittleEndianExplicit, nullptr);
    if (c.bad() || !ds->canWriteXfer(EXS_LittleEndianExplicit))
        return sf_fail(err, SF_EINVAL, where, "the compressed pixel data does not decode: %s",
                       c.bad() ? c.text() : "its frames do not make the image");
    Uint16 now_bits = 0, now_spp = 1, now_stored = 0;
    ds->findAndGetUint16(DCM_BitsAllocated, now_bits);
    ds->findAndGetUint16(DCM_SamplesPerPixel, now_spp);
    if (now_bits != bits || now_spp != 1)
        return sf_fail(err, SF_EINVAL, where, "%s", "the compressed samples are not of the width the header says "
                       "(BitsAllocated, SamplesPerPixel)");
    if (ds->findAndGetUint16(DCM_BitsStored, now_stored).good() && now_stored > 0 && now_stored <= bits)
        *stored = now_stored;
    return 0;
}

/* A JPEG 2000 frame (ds: a data set of one frame) decoded by OpenJPEG (j2k.h: Debian's DCMTK has no
 * codec for it): its fragments laid end to end, the samples put back as the pixel data in place of
 * the encapsulated ones (16 or 8 bits a sample, BitsAllocated). 0, or SF_EINVAL / SF_ENOMEM at where. */
static inline int decode_j2k(DcmDataset *ds, E_TransferSyntax xfer, unsigned bits, unsigned stored, bool is_signed,
                             const char *where, struct sf_err *err)
{
    DcmElement *e = nullptr;
    DcmPixelSequence *seq = nullptr;
    Uint16 rows = 0, cols = 0;
    ds->findAndGetUint16(DCM_Rows, rows), ds->findAndGetUint16(DCM_Columns, cols);
    if ((bits != 8 && bits != 16) || stored < 1 || stored > bits)
        return sf_fail(err, SF_EINVAL, where, "JPEG 2000 frames of %u bits (BitsStored %u) are not read: 8 or 16", bits,
                       stored);
    if (ds->findAndGetElement(DCM_PixelData, e).bad() || !e ||
        static_cast<DcmPixelData *>(e)->getEncapsulatedRepresentation(xfer, nullptr, seq).bad() || !seq)
        return sf_fail(err, SF_EINVAL, where, "the JPEG 2000 pixel data is not encapsulated");
    std::vector<unsigned char> stream; /* the fragments after the offset table, end to end */
    size_t frame_bytes = (size_t)rows * cols * (bits / 8);
    bool first = true;
    for (DcmObject *o = seq->nextInContainer(nullptr); o; o = seq->nextInContainer(o), first = false) {
        DcmPixelItem *it = static_cast<DcmPixelItem *>(o);
        Uint8 *d = nullptr;
        Uint32 n = it->getLength();
        if (first || !n)
            continue;
        if (stream.size() + n > 2 * frame_bytes + 65536) /* (a lossless stream is smaller than its samples) */
            return sf_fail(err, SF_EINVAL, where, "the JPEG 2000 fragments hold more than twice the frame's samples");
        if (it->getUint8Array(d).bad() || !d)
            return sf_fail(err, SF_EINVAL, where, "a JPEG 2000 fragment cannot be read");
        stream.insert(stream.end(), d, d + n);
    }
    std::vector<uint16_t> out((size_t)rows * cols);
    struct j2k_frame f = {rows, cols, (int)stored, is_signed};
    int rc = j2k_decode(stream.data(), stream.size(), &f, out.data(), where, err);
    if (rc)
        return rc;
    OFCondition c;
    if (bits == 16) {
        c = ds->putAndInsertUint16Array(DCM_PixelData, out.data(), (unsigned long)out.size());
    } else {
        std::vector<Uint8> narrow(out.begin(), out.end());
        c = ds->putAndInsertUint8Array(DCM_PixelData, narrow.data(), (unsigned long)narrow.size());
    }
    return c.bad() ? sf_fail(err, SF_ENOMEM, where, "out of memory for the frame's samples") : 0;
}

/* A sample's value: its stored low bits (BitsStored; all of bits when 0 or more), two's complement
 * when signed (the bits above them are not the sign: writers and decoders leave them as they are). */
static inline double stored_value(unsigned bits, unsigned stored, bool is_signed, uint32_t raw)
{
    unsigned b = stored >= bits || stored == 0 ? bits : stored;
    uint64_t v = raw & (b >= 32 ? 0xffffffffull : (1ull << b) - 1);
    if (is_signed && (v >> (b - 1)) & 1)
        return (double)v - (double)(1ull << b);
    return (double)v;
}

/* Whether ds is one multi-frame image, which frames_read reads: NumberOfFrames over 1, or an RT
 * Dose, a Segmentation or an image with per-frame functional groups (whatever its frames). */
bool frames_multiframe(DcmDataset *ds);
/* ds (read from part k as dcmtk_in.h reads it; pixel data in its original transfer syntax) to out,
 * as series_read says; segment: ?segment (0: none given); as_labels: a Segmentation as a label map. */
int frames_read(DcmDataset *ds, int k, bool check_only, size_t max_samples, int segment, bool as_labels,
                struct series *out, struct sf_err *err);

#endif
