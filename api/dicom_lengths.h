/* dicom_lengths.h - whether every element of a DICOM object (a slice of a series, an RT
 * Structure Set), at any depth, declares a length that fits in what is left of the buffer.
 * DCMTK allocates an element's value at its declared length before it looks at what is left (a
 * 20-byte part declaring 2.3 GB asked for 2.3 GB: found by fuzz_volume), so the readers call
 * this first. The walk: the file meta header (group 0002, explicit VR little endian, after
 * "DICM" at 0 or 128), then the data set (implicit VR when its first element has no VR), stepping
 * into sequences and items (the dictionary says which implicit elements are sequences) and over
 * other values. What the walk does not understand it leaves to DCMTK (true). */
#ifndef SURFD_DICOM_LENGTHS_H
#define SURFD_DICOM_LENGTHS_H

#include <stdbool.h>
#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

bool dicom_lengths_fit(const void *data, size_t len);

#ifdef __cplusplus
}
#endif

#endif
