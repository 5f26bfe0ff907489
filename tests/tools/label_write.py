"""label_write.py - label maps for the tests, written with struct and gzip alone (independently of
api/volume_io.c, which reads them): the shared CT crop cut into labels, as NRRD with the key/value
pairs 3D Slicer writes for its segments (Segment<k>_Name, Segment<k>_LabelValue), as MetaImage
(.mha) and as raw samples; NIfTI through nifti_write.py.

  labels(samples, cuts)           int16 samples -> label of each: cuts [(upper bound, label)], 0 past the last
  nrrd(path, data, dims, type, segments=[(value, name)], gz=False, spacing=(1, 1, 1), origin=(0, 0, 0))
  mha(path, data, dims, type, spacing=(1, 1, 1), origin=(0, 0, 0))"""
import gzip
import struct

NRRD_TYPES = {"uint8": "unsigned char", "int16": "short", "uint16": "unsigned short", "float32": "float"}
MHA_TYPES = {"uint8": "MET_UCHAR", "int16": "MET_SHORT", "uint16": "MET_USHORT", "float32": "MET_FLOAT"}
FORMATS = {"uint8": "B", "int16": "h", "uint16": "H", "float32": "f"}


def labels(samples, cuts):
    """cuts: [(lo, hi, label)]: a sample in (lo, hi] gets label, else 0."""
    out = []
    for v in samples:
        lab = 0
        for lo, hi, l in cuts:
            if lo < v <= hi:
                lab = l
        out.append(lab)
    return out


def pack(values, type):
    return struct.pack("<%d%s" % (len(values), FORMATS[type]), *values)


def nrrd(path, data, dims, type, segments=(), gz=False, spacing=(1, 1, 1), origin=(0, 0, 0)):
    lines = ["NRRD0004", "type: " + NRRD_TYPES[type], "dimension: 3", "space: left-posterior-superior",
             "sizes: %d %d %d" % dims,
             "space directions: (%g,0,0) (0,%g,0) (0,0,%g)" % spacing, "kinds: domain domain domain",
             "endian: little", "encoding: " + ("gzip" if gz else "raw"), "space origin: (%g,%g,%g)" % origin]
    for k, (value, name) in enumerate(segments):  # as Slicer writes them: its keys in order, per segment
        lines += ["Segment%d_Color:=0.5 0.5 0.5" % k, "Segment%d_ID:=Segment_%d" % (k, k + 1),
                  "Segment%d_LabelValue:=%d" % (k, value), "Segment%d_Layer:=0" % k, "Segment%d_Name:=%s" % (k, name),
                  "Segment%d_Tags:=Segmentation.Status:inprogress|" % k]
    head = ("\n".join(lines) + "\n\n").encode("utf-8")
    with open(path, "wb") as f:
        f.write(head + (gzip.compress(data) if gz else data))


def mha(path, data, dims, type, spacing=(1, 1, 1), origin=(0, 0, 0)):
    head = ("ObjectType = Image\nNDims = 3\nBinaryData = True\nBinaryDataByteOrderMSB = False\n"
            "Offset = %g %g %g\nElementSpacing = %g %g %g\nDimSize = %d %d %d\nElementType = %s\n"
            "ElementDataFile = LOCAL\n" % (origin + spacing + dims + (MHA_TYPES[type],)))
    with open(path, "wb") as f:
        f.write(head.encode() + data)
