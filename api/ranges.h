/* ranges.h - the ranges a volume's geometry and iso value keep, whatever format brought them
 * (volume_io.c: raw samples, NRRD, MetaImage, FRep grids; series_dcmtk.cpp: DICOM series), so
 * that every product the grid and the mesh make of them stays finite and a mesh's float32
 * vertices still tell its cells apart. Past them a request is refused with a 422 naming the field,
 * never read into a mesh of volume 0 or an allocation sized by an overflow.
 *
 * Patient coordinates are within a metre or two of the scanner's origin: 1 km is room for any
 * table offset. 1 um is finer than micro-CT's pixels, 10 m coarser than any scanner's. */
#ifndef SURFD_RANGES_H
#define SURFD_RANGES_H

#define RANGE_MAX_COORD 1e6    /* mm from 0: a grid's origin and its far corner, a slice's position */
#define RANGE_MIN_SPACING 1e-3 /* mm between samples */
#define RANGE_MAX_SPACING 1e4  /* mm */
#define RANGE_MAX_ISO 1e30     /* |iso|: finite in float32 (the samples' widest type) with room to spare */
/* The smallest cell, relative to its distance from 0, whose corners float32 vertices hold apart:
 * 2^-20 is 8 float steps a cell (a vertex placed to an eighth of its cell), which still takes 1 um
 * cells 950 mm out and 1 mm cells anywhere in range. */
#define RANGE_MIN_CELL_REL (1.0 / 1048576) /* 2^-20 */

#endif
