// instance_dcmtk.cpp - one DICOM instance's UIDs and geometry through DCMTK (dicom_instance.h),
// pixel data left unread (DCMTK's maxReadLength): a CT slice's 512 KB are not copied to list it.
#include "dcmtk_in.h"
#include "dicom_instance.h"

#include <cmath>
#include <cstdio>
#include <cstring>

namespace {

/* A text value of tag into out (cap bytes), trimmed: false when absent or longer. */
bool text(DcmItem *ds, const DcmTagKey &tag, char *out, size_t cap)
{
    OFString s;
    out[0] = 0;
    if (ds->findAndGetOFString(tag, s).bad())
        return false;
    size_t a = 0, b = s.length();
    while (a < b && s[a] == ' ')
        a++;
    while (b > a && (s[b - 1] == ' ' || s[b - 1] == '\0'))
        b--;
    if (b - a >= cap)
        return false;
    memcpy(out, s.c_str() + a, b - a);
    out[b - a] = 0;
    return true;
}

/* n finite doubles of tag: false when absent, short or not finite. */
bool doubles(DcmItem *ds, const DcmTagKey &tag, double *v, unsigned n)
{
    for (unsigned k = 0; k < n; k++) {
        Float64 f;
        if (ds->findAndGetFloat64(tag, f, k).bad() || !std::isfinite(f))
            return false;
        v[k] = f;
    }
    return true;
}

int read(const void *data, size_t len, const char *pointer, struct dicom_instance *out, struct sf_err *err)
{
    DcmFileFormat ff;
    int rc = dcm_read_object(data, len, pointer, 4096, ff, err);
    if (rc)
        return rc;
    DcmDataset *ds = ff.getDataset();
    static const struct {
        const DcmTagKey &tag;
        const char *name;
        size_t off;
    } UIDS[] = {{DCM_SOPInstanceUID, "SOPInstanceUID", offsetof(dicom_instance, sop_uid)},
                {DCM_SeriesInstanceUID, "SeriesInstanceUID", offsetof(dicom_instance, series_uid)},
                {DCM_StudyInstanceUID, "StudyInstanceUID", offsetof(dicom_instance, study_uid)},
                {DCM_SOPClassUID, "SOPClassUID", offsetof(dicom_instance, sop_class)}};
    for (const auto &u : UIDS) {
        char *dst = (char *)out + u.off;
        if (!text(ds, u.tag, dst, 65) || !dicom_uid_valid(dst))
            return sf_fail(err, SF_EINVAL, pointer, "%s is missing or is not a UID (digits and dots, at most 64)",
                           u.name);
    }
    if (text(ds, DCM_FrameOfReferenceUID, out->frame_uid, sizeof out->frame_uid) && !dicom_uid_valid(out->frame_uid))
        out->frame_uid[0] = 0;
    if (!text(ds, DCM_Modality, out->modality, sizeof out->modality))
        out->modality[0] = 0;
    for (char *p = out->modality; *p; p++) /* a code string: capitals, digits, space and underscore */
        if (!((*p >= 'A' && *p <= 'Z') || (*p >= '0' && *p <= '9') || *p == '_' || *p == ' '))
            *p = '_';
    Uint16 rows = 0, cols = 0;
    if (ds->findAndGetUint16(DCM_Rows, rows).good() && ds->findAndGetUint16(DCM_Columns, cols).good())
        out->rows = rows, out->columns = cols;
    Sint32 frames = 1;
    out->frames = ds->findAndGetSint32(DCM_NumberOfFrames, frames).good() && frames > 0 ? frames : 1;
    out->has_plane = doubles(ds, DCM_PixelSpacing, out->spacing, 2) &&
                     doubles(ds, DCM_ImagePositionPatient, out->position, 3) &&
                     doubles(ds, DCM_ImageOrientationPatient, out->orientation, 6);
    return 0;
}

} // namespace

extern "C" bool dicom_uid_valid(const char *s)
{
    size_t n = strlen(s);
    if (n < 1 || n > 64 || s[0] == '.' || s[n - 1] == '.')
        return false;
    for (size_t k = 0; k < n; k++)
        if (!((s[k] >= '0' && s[k] <= '9') || (s[k] == '.' && s[k + 1] != '.')))
            return false;
    return true;
}

extern "C" int dicom_instance_read(const void *data, size_t len, const char *pointer, struct dicom_instance *out,
                                   struct sf_err *err)
{
    memset(out, 0, sizeof *out);
    try { /* DCMTK's allocations may throw: never past C */
        return read(data, len, pointer, out, err);
    } catch (const std::bad_alloc &) {
        return sf_fail(err, SF_ENOMEM, pointer, "out of memory for the instance");
    }
}
