"""nifti_write.py - NIfTI-1 and NIfTI-2 single files for the tests, written by the standard's offsets
(nifti1.h, nifti2.h) with struct and gzip alone: independently of api/nifti.c, which reads them.

  write(path, data, dims, datatype, bitpix, sform=None, qform=None, pixdim=(1, 1, 1), version=1, ...)
    sform: the 3x4 voxel-to-RAS affine (rows); qform: (b, c, d, qx, qy, qz, qfac) with pixdim;
    neither: the pixdims alone. big: big-endian. gz: the file gzipped. magic, dim0, dim4: overrides
    for the bad files. extensions: [(ecode, bytes)] written after the header (each padded to 16
    bytes); intent_name: the header's (16 bytes at most)."""
import gzip
import struct


def write(path, data, dims, datatype, bitpix, sform=None, qform=None, pixdim=(1, 1, 1), version=1, gz=False,
          slope=0.0, inter=0.0, units=2, big=False, magic=None, dim0=3, dim4=1, extension=0, extensions=None,
          intent_name=b""):
    """extension: bytes of an (empty) extension between the header and the samples (vox_offset grows)."""
    e = ">" if big else "<"
    ext = b""
    for code, body in extensions or []:
        size = (8 + len(body) + 15) // 16 * 16
        ext += struct.pack(e + "ii", size, code) + body + b"\0" * (size - 8 - len(body))
    extension += len(ext)
    qfac = qform[6] if qform else 1.0
    dim = [dim0] + list(dims) + [dim4, 1, 1, 1]
    pix = [qfac] + list(pixdim) + [0, 0, 0, 0]
    if version == 1:
        h = bytearray(348)
        struct.pack_into(e + "i", h, 0, 348)
        struct.pack_into(e + "8h", h, 40, *dim)
        struct.pack_into(e + "hh", h, 70, datatype, bitpix)
        struct.pack_into(e + "8f", h, 76, *pix)
        struct.pack_into(e + "fff", h, 108, 352.0 + extension, slope, inter)
        h[123] = units
        if qform:
            struct.pack_into(e + "h", h, 252, 1)
            struct.pack_into(e + "6f", h, 256, *qform[:6])
        if sform:
            struct.pack_into(e + "h", h, 254, 1)
            struct.pack_into(e + "12f", h, 280, *[v for row in sform for v in row])
        h[328:328 + len(intent_name)] = intent_name
        h[344:348] = magic or b"n+1\0"
    else:
        h = bytearray(540)
        struct.pack_into(e + "i", h, 0, 540)
        h[4:12] = magic or b"n+2\0\r\n\x1a\n"
        struct.pack_into(e + "hh", h, 12, datatype, bitpix)
        struct.pack_into(e + "8q", h, 16, *dim)
        struct.pack_into(e + "8d", h, 104, *pix)
        struct.pack_into(e + "q", h, 168, 544 + extension)
        struct.pack_into(e + "dd", h, 176, slope, inter)
        if qform:
            struct.pack_into(e + "i", h, 344, 1)
            struct.pack_into(e + "6d", h, 352, *qform[:6])
        if sform:
            struct.pack_into(e + "i", h, 348, 1)
            struct.pack_into(e + "12d", h, 400, *[v for row in sform for v in row])
        struct.pack_into(e + "i", h, 500, units)
        h[508:508 + len(intent_name)] = intent_name
    out = bytes(h) + (b"\1\0\0\0" + ext + b"\0" * (extension - len(ext)) if ext else b"\0" * (4 + extension)) + data
    with open(path, "wb") as f:
        f.write(gzip.compress(out) if gz else out)
