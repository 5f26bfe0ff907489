/* dicom_instance.h - what the store keeps of one DICOM instance a PACS sends or surfd pulls
 * (daemon/dicom_node.c, GET /series): its UIDs, modality and SOP class, and the geometry a series'
 * listing says (rows, columns, frames, pixel spacing, position, orientation), read through DCMTK
 * after dicom_scan.h's pass (instance_dcmtk.cpp). No patient element is read. */
#ifndef SURFD_DICOM_INSTANCE_H
#define SURFD_DICOM_INSTANCE_H

#include <stdbool.h>
#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

#include "../core/base/err.h"

struct dicom_instance {
    char sop_uid[65], series_uid[65], study_uid[65], sop_class[65], frame_uid[65];
    char modality[17];
    unsigned rows, columns;  /* 0: no pixel data (an RT Structure Set, a report) */
    long frames;             /* NumberOfFrames, 1 when absent */
    bool has_plane;          /* pixel spacing, position and orientation given (a classic slice's) */
    double spacing[2], position[3], orientation[6];
};

/* Reads data (a Part 10 file, or a bare data set) into out: 0, or SF_EFORMAT (not DICOM as
 * dicom_scan reads it), SF_EINVAL (a UID missing or not a UID: digits and dots, 64 at most),
 * SF_ELIMIT, with pointer as err's pointer. */
int dicom_instance_read(const void *data, size_t len, const char *pointer, struct dicom_instance *out,
                        struct sf_err *err);

/* Whether s is a UID (PS3.5 9.1: digits and dots, 1 to 64 characters, no empty component). */
bool dicom_uid_valid(const char *s);

#ifdef __cplusplus
}
#endif

#endif
