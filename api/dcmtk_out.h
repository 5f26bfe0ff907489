// dcmtk_out.h - what the DCMTK shims that write objects share (rtstruct_dcmtk.cpp,
// dicom_stl_dcmtk.cpp): a DICOM Part 10 object into memory, a UID given or fresh, the date and time
// now. C++, included by those shims only.
#ifndef SURFD_DCMTK_OUT_H
#define SURFD_DCMTK_OUT_H

#include <dcmtk/config/osconfig.h>
#include <dcmtk/dcmdata/dctk.h>
#include <dcmtk/dcmdata/dcostrmb.h>

#include <cstdio>
#include <cstdlib>

extern "C" { /* a C header */
#include "../core/base/err.h"
}

/* ff (explicit little endian) into *out (caller frees); what names it in errors. */
static inline int dcm_write_object(DcmFileFormat &ff, unsigned char **out, size_t *out_len, const char *what,
                                   struct sf_err *err)
{
    const E_TransferSyntax xfer = EXS_LittleEndianExplicit;
    if (ff.validateMetaInfo(xfer).bad())
        return sf_fail(err, SF_EBACKEND, "", "DCMTK could not make %s's meta header", what);
    size_t cap = (size_t)ff.calcElementLength(xfer, EET_ExplicitLength) + 1024;
    unsigned char *mem = (unsigned char *)malloc(cap);
    if (!mem)
        return sf_fail(err, SF_ENOMEM, "", "out of memory");
    DcmOutputBufferStream os(mem, (offile_off_t)cap);
    ff.transferInit();
    OFCondition c = ff.write(os, xfer, EET_ExplicitLength, NULL);
    ff.transferEnd();
    void *written = NULL;
    offile_off_t n = 0;
    os.flushBuffer(written, n);
    if (c.bad()) {
        free(mem);
        return sf_fail(err, SF_EBACKEND, "", "DCMTK could not write %s: %s", what, c.text());
    }
    *out = mem;
    *out_len = (size_t)n;
    return 0;
}

/* given when it is a UID, else a fresh one under root, into uid[100]. */
static inline const char *dcm_uid(char uid[100], const char *given, const char *root)
{
    if (given && *given)
        snprintf(uid, 100, "%s", given);
    else
        dcmGenerateUniqueIdentifier(uid, root);
    return uid;
}

/* Today as DA (YYYYMMDD) and now as TM (HHMMSS). */
static inline void dcm_now(char date[16], char tm[16])
{
    OFDateTime now = OFDateTime::getCurrentDateTime();
    OFString d, t;
    now.getDate().getISOFormattedDate(d, false);
    now.getTime().getISOFormattedTime(t, true, false, false, false);
    snprintf(date, 16, "%s", d.c_str());
    snprintf(tm, 16, "%s", t.c_str());
}

#endif
