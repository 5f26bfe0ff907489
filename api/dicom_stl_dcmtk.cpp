// dicom_stl_dcmtk.cpp - DCMTK for Encapsulated STL (dicom_stl.h): the modules of PS3.3 A.85 - Patient
// and General Study (type 2 elements empty), Encapsulated Document Series (modality M3D), Frame of
// Reference, Enhanced General Equipment, Encapsulated Document (MIME type model/stl), Manufacturing
// 3D Model (units: mm, UCUM) and SOP Common - around the file's bytes.
#include "dicom_stl.h"

#include <cstring>
#include <string>

#include "dcmtk_out.h"

static const char ENCAPSULATED_STL_SOP_CLASS[] = "1.2.840.10008.5.1.4.1.1.104.3";

/* A code sequence item (value, scheme, meaning) under tag of it. */
static bool code(DcmItem *it, const DcmTagKey &tag, const char *value, const char *scheme, const char *meaning)
{
    DcmItem *c = NULL;
    return it->findOrCreateSequenceItem(tag, c, -2).good() && c->putAndInsertString(DCM_CodeValue, value).good() &&
           c->putAndInsertString(DCM_CodingSchemeDesignator, scheme).good() &&
           c->putAndInsertString(DCM_CodeMeaning, meaning).good();
}

extern "C" int dicom_stl_wrap(const void *stl, size_t len, const char *title, const char *study_uid,
                              const char *frame_uid, unsigned char **out, size_t *out_len, struct sf_err *err)
{
    *out = NULL;
    *out_len = 0;
    if (len > 0xFFFFFFF0u)
        return sf_fail(err, SF_ELIMIT, "?format", "the STL is over 4 GiB, more than one DICOM element holds");
    DcmFileFormat ff;
    DcmDataset *ds = ff.getDataset();
    char sop[100], series[100], study[100], frame[100], date[16], tm[16];
    dcm_uid(sop, NULL, SITE_INSTANCE_UID_ROOT);
    dcm_uid(series, NULL, SITE_SERIES_UID_ROOT);
    dcm_uid(study, study_uid, SITE_STUDY_UID_ROOT);
    dcm_uid(frame, frame_uid, SITE_INSTANCE_UID_ROOT);
    dcm_now(date, tm);
    std::string when = std::string(date) + tm;
    static const DcmTagKey EMPTY[] = {DCM_PatientName, DCM_PatientID, DCM_PatientBirthDate, DCM_PatientSex,
                                      DCM_StudyDate, DCM_StudyTime, DCM_ReferringPhysicianName, DCM_StudyID,
                                      DCM_AccessionNumber, DCM_PositionReferenceIndicator, DCM_ConceptNameCodeSequence};
    bool ok = ds->putAndInsertString(DCM_SpecificCharacterSet, "ISO_IR 192").good() &&
              ds->putAndInsertString(DCM_SOPClassUID, ENCAPSULATED_STL_SOP_CLASS).good() &&
              ds->putAndInsertString(DCM_SOPInstanceUID, sop).good() &&
              ds->putAndInsertString(DCM_StudyInstanceUID, study).good() &&
              ds->putAndInsertString(DCM_SeriesInstanceUID, series).good() &&
              ds->putAndInsertString(DCM_Modality, "M3D").good() &&
              ds->putAndInsertString(DCM_SeriesNumber, "1").good() &&
              ds->putAndInsertString(DCM_InstanceNumber, "1").good() &&
              ds->putAndInsertString(DCM_FrameOfReferenceUID, frame).good() &&
              ds->putAndInsertString(DCM_Manufacturer, "surfd").good() &&
              ds->putAndInsertString(DCM_ManufacturerModelName, "surfd").good() &&
              ds->putAndInsertString(DCM_DeviceSerialNumber, "1").good() &&
              ds->putAndInsertString(DCM_SoftwareVersions, "surfd").good() &&
              ds->putAndInsertString(DCM_ContentDate, date).good() && ds->putAndInsertString(DCM_ContentTime, tm).good() &&
              ds->putAndInsertString(DCM_InstanceCreationDate, date).good() &&
              ds->putAndInsertString(DCM_InstanceCreationTime, tm).good() &&
              ds->putAndInsertString(DCM_AcquisitionDateTime, when.c_str()).good() &&
              ds->putAndInsertString(DCM_BurnedInAnnotation, "NO").good() &&
              ds->putAndInsertString(DCM_DocumentTitle, title && *title ? title : "surfd model").good() &&
              ds->putAndInsertString(DCM_MIMETypeOfEncapsulatedDocument, "model/stl").good() &&
              ds->putAndInsertUint32(DCM_EncapsulatedDocumentLength, (Uint32)len).good() &&
              code(ds, DCM_MeasurementUnitsCodeSequence, "mm", "UCUM", "mm");
    for (size_t k = 0; ok && k < sizeof EMPTY / sizeof *EMPTY; k++) /* the last an empty sequence */
        ok = ds->insertEmptyElement(EMPTY[k]).good();
    /* OB of even length: an odd file gets one pad byte, EncapsulatedDocumentLength says the true one */
    size_t even = len + (len & 1);
    Uint8 *bytes = NULL;
    if (ok) {
        DcmOtherByteOtherWord *ob = new DcmOtherByteOtherWord(DcmTag(DCM_EncapsulatedDocument, EVR_OB));
        ok = ob->createUint8Array((Uint32)even, bytes).good() && bytes;
        if (ok) {
            memcpy(bytes, stl, len);
            if (even > len)
                bytes[len] = 0;
            ok = ds->insert(ob, true).good();
        } else {
            delete ob;
        }
    }
    if (!ok)
        return sf_fail(err, SF_ENOMEM, "", "out of memory wrapping the STL");
    return dcm_write_object(ff, out, out_len, "the Encapsulated STL", err);
}
