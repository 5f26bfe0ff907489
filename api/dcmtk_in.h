// dcmtk_in.h - how the DCMTK shims that read objects (rtstruct_dcmtk.cpp, series_dcmtk.cpp) read
// one: the structure pass first (dicom_scan.h), then DCMTK in the encoding the pass read it in.
// Without a meta header DCMTK would guess the encoding from its dictionary, and may frame the
// bytes otherwise than the pass did (fuzz_dicom_scan: a 259-byte part read big endian declared
// 4 GB, which DCMTK allocated); so such a data set is read in the pass's encoding, and one with
// a meta header in the transfer syntax it names, which both read alike. C++, for those shims.
#ifndef SURFD_DCMTK_IN_H
#define SURFD_DCMTK_IN_H

#include <dcmtk/config/osconfig.h>
#include <dcmtk/dcmdata/dcistrmb.h>
#include <dcmtk/dcmdata/dctk.h>

#include "dicom_scan.h"

/* buf into ff (max_read: values longer are left unread, DCMTK's maxReadLength): 0, or SF_EFORMAT
 * (not DICOM, or not as the pass reads it), SF_EINVAL (a transfer syntax DCMTK does not know) or
 * SF_ELIMIT, with pointer as err's pointer. */
static inline int dcm_read_object(const void *buf, size_t len, const char *pointer, Uint32 max_read, DcmFileFormat &ff,
                                  struct sf_err *err)
{
    struct dicom_scan_stats st;
    int rc = dicom_scan(buf, len, pointer, &st, err);
    if (rc)
        return rc;
    bool meta = st.transfer_syntax[0] != 0;
    E_TransferSyntax xfer = meta ? DcmXfer(st.transfer_syntax).getXfer()
                            : st.implicit ? (st.big_endian ? EXS_BigEndianImplicit : EXS_LittleEndianImplicit)
                                          : (st.big_endian ? EXS_BigEndianExplicit : EXS_LittleEndianExplicit);
    if (xfer == EXS_Unknown)
        return sf_fail(err, SF_EINVAL, pointer, "transfer syntax %s is not one surfd reads", st.transfer_syntax);
    DcmInputBufferStream in;
    in.setBuffer(buf, (offile_off_t)len);
    in.setEos();
    OFCondition c;
    if (meta) {
        ff.transferInit();
        c = ff.read(in, EXS_Unknown, EGL_noChange, max_read);
        ff.transferEnd();
    } else {
        DcmDataset *ds = ff.getDataset();
        ds->transferInit();
        c = ds->read(in, xfer, EGL_noChange, max_read);
        ds->transferEnd();
    }
    if (c.bad())
        return sf_fail(err, SF_EFORMAT, pointer, "not a readable DICOM object: %s", c.text());
    return 0;
}

#endif
