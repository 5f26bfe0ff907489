/* dicom_stl.h - a binary STL wrapped as a DICOM Encapsulated STL object (SOP class
 * 1.2.840.10008.5.1.4.1.1.104.3, PS3.3 A.85), through DCMTK behind dicom_stl_dcmtk.cpp: the mesh
 * in patient coordinates (mm) for a planning system or PACS that stores surfaces; it references
 * study_uid and frame_uid (NULL or "": fresh ones); the patient's elements are present and empty. */
#ifndef SURFD_DICOM_STL_H
#define SURFD_DICOM_STL_H

#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

#include "../core/base/err.h"

int dicom_stl_wrap(const void *stl, size_t len, const char *title, const char *study_uid, const char *frame_uid,
                   unsigned char **out, size_t *out_len, struct sf_err *err);

#ifdef __cplusplus
}
#endif

#endif
