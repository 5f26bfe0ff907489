/* cube.h - the cell's geometry the extractions of core/iso share (mc.c, adapt.c). */
#ifndef SURFD_CUBE_H
#define SURFD_CUBE_H

/* Each face's corners counter-clockwise about its outward normal: -x, +x, -y, +y, -z, +z;
 * corner c = x + 2y + 4z. */
extern const int iso_face_ccw[6][4];

#endif
