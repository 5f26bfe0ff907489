#!/usr/bin/python3
"""Writes the multi-frame DICOM objects surfd's tests read, with pydicom and numpy (Debian's
python3-pydicom, python3-numpy): an Enhanced CT made from a classic series (each slice a frame,
placed by its Per-frame Functional Groups, PS3.3 C.7.6.16), an RT Dose of an analytic dose field
(C.8.8.3: GridFrameOffsetVector, DoseGridScaling) and a Segmentation of known shapes (C.8.20:
BINARY, 1 bit, or FRACTIONAL, 8 bits; frames only where each segment lies). Each function also
returns what the test compares with (the dose grid in Gy, the segments' label grids).

  dicom_write.py enhanced SERIES_DIR OUT [shared-rescale] [shuffle]
  dicom_write.py dose OUT [bits=16|32] [offsets=relative|absolute|reversed] [scaling=no] [uneven=K]
  dicom_write.py seg OUT [type=binary|fractional]
  dicom_write.py rtstruct OUT          (the sparse ROIs a planning system draws, and a dense one)
  dicom_write.py j2k SERIES_DIR OUT_DIR [tiles]  (each slice's pixels as JPEG 2000 lossless, by opj_compress)
  dicom_write.py j2k-frames IMAGE OUT   (a multi-frame image's frames each as JPEG 2000 lossless)
  dicom_write.py seeds SMALL_SERIES_DIR OUT_DIR   (tests/fuzz/seeds/frames: each kind, small)
  dicom_write.py counts SMALL_SERIES_DIR OUT_DIR  (tests/fuzz/crashers/frames: counts that were
                                                    walked quadratically, each file under 256 KB)
"""
import os
import random
import sys

import numpy as np
import pydicom
from pydicom.dataset import Dataset, FileMetaDataset
from pydicom.sequence import Sequence
from pydicom.uid import ExplicitVRLittleEndian, generate_uid

ENHANCED_CT = "1.2.840.10008.5.1.4.1.1.2.1"
RT_DOSE = "1.2.840.10008.5.1.4.1.1.481.2"
SEGMENTATION = "1.2.840.10008.5.1.4.1.1.66.4"


# The people an object names (PS3.15 E.1-1 lists each; the daemon blanks them before it stores the
# upload): _base writes the study's, seg() its Content Creator's Name, dose() a Reviewer Name.
PEOPLE = {
    "ReferringPhysicianName": "Referrer^Rita",
    "ConsultingPhysicianName": "Consultant^Cora",
    "PhysiciansOfRecord": "Record^Rob",
    "PerformingPhysicianName": "Performer^Paula",
    "OperatorsName": "Operator^Otto",
    "ContentCreatorName": "Creator^Carla",
    "ReviewerName": "Reviewer^Rex",
}


def _base(sop_class, modality):
    ds = Dataset()
    ds.file_meta = FileMetaDataset()
    ds.file_meta.MediaStorageSOPClassUID = sop_class
    ds.file_meta.MediaStorageSOPInstanceUID = generate_uid()
    ds.file_meta.TransferSyntaxUID = ExplicitVRLittleEndian
    ds.is_little_endian, ds.is_implicit_VR = True, False
    ds.SOPClassUID = sop_class
    ds.SOPInstanceUID = ds.file_meta.MediaStorageSOPInstanceUID
    ds.Modality = modality
    ds.PatientName = "Doe^Jane"  # blanked by the daemon before it stores the upload
    ds.PatientID = "SURFD-TEST-4711"
    for k in ("ReferringPhysicianName", "ConsultingPhysicianName", "PhysiciansOfRecord", "PerformingPhysicianName",
              "OperatorsName"):
        setattr(ds, k, PEOPLE[k])
    ds.StudyInstanceUID, ds.SeriesInstanceUID = generate_uid(), generate_uid()
    ds.FrameOfReferenceUID = generate_uid()
    ds.SamplesPerPixel = 1
    ds.PhotometricInterpretation = "MONOCHROME2"
    return ds


def _item(**kw):
    it = Dataset()
    for k, v in kw.items():
        setattr(it, k, v)
    return it


def _save(ds, out):
    ds.save_as(out, write_like_original=False)


def enhanced(series_dir, out, shared_rescale=False, shuffle=False):
    """The classic series in series_dir as one Enhanced CT, a frame a slice (shuffled: frames in no
    order of position), positions per frame, orientation and pixel measures shared, the rescale
    per frame or shared. Per frame, each frame's intercept is its own: frame k's stored values are
    raised by 4 (k + 1) and its intercept lowered by as much (times the slope), so the rescaled
    values are the series' and a reader taking one frame's rescale for all would miss them."""
    sl = [pydicom.dcmread(os.path.join(series_dir, f)) for f in sorted(os.listdir(series_dir))]
    if shuffle:
        random.Random(47).shuffle(sl)
    a = sl[0]
    ds = _base(ENHANCED_CT, "CT")
    for k in ("Rows", "Columns", "BitsAllocated", "BitsStored", "HighBit", "PixelRepresentation"):
        setattr(ds, k, getattr(a, k))
    ds.NumberOfFrames = len(sl)
    shared = _item(PlaneOrientationSequence=Sequence([_item(ImageOrientationPatient=a.ImageOrientationPatient)]),
                   PixelMeasuresSequence=Sequence([_item(PixelSpacing=a.PixelSpacing,
                                                         SliceThickness=a.get("SliceThickness", 1))]))
    rescale = lambda s, d=0: _item(RescaleSlope=s.get("RescaleSlope", 1),
                                   RescaleIntercept="%.10g" % (float(s.get("RescaleIntercept", 0)) -
                                                               d * float(s.get("RescaleSlope", 1))),
                                   RescaleType="HU")
    if shared_rescale:
        shared.PixelValueTransformationSequence = Sequence([rescale(a)])
    ds.SharedFunctionalGroupsSequence = Sequence([shared])
    per, pixels = [], []
    signed, bits = a.PixelRepresentation == 1, int(a.BitsStored)
    top = 2 ** (bits - 1) - 1 if signed else 2 ** bits - 1
    for k, s in enumerate(sl):
        it = _item(PlanePositionSequence=Sequence([_item(ImagePositionPatient=s.ImagePositionPatient)]))
        d = 0 if shared_rescale else 4 * (k + 1)
        if not shared_rescale:
            it.PixelValueTransformationSequence = Sequence([rescale(s, d)])
        px = np.frombuffer(s.PixelData, dtype="<i2" if signed else "<u2").astype(np.int64)
        if a.BitsAllocated != 16 or px.max() + d > top:
            raise ValueError("%s: no room for a per-frame intercept" % series_dir)
        pixels.append((px + d).astype("<i2" if signed else "<u2").tobytes())
        per.append(it)
    ds.PerFrameFunctionalGroupsSequence = Sequence(per)
    ds.PixelData = b"".join(pixels)
    _save(ds, out)


def dose_field(shape=(30, 36, 40), spacing=(2.5, 2.0, 3.0), origin=(-45.0, -40.0, -42.0)):
    """A dose in Gy on a grid (z, y, x): an ellipsoidal Gaussian of 60 Gy whose 20 Gy isodose lies
    well inside the grid. The grid's x, y, z in mm."""
    nz, ny, nx = shape
    x = origin[0] + spacing[0] * np.arange(nx)
    y = origin[1] + spacing[1] * np.arange(ny)
    z = origin[2] + spacing[2] * np.arange(nz)
    Z, Y, X = np.meshgrid(z, y, x, indexing="ij")
    r2 = ((X - 5.0) / 18.0) ** 2 + ((Y + 3.0) / 14.0) ** 2 + ((Z - 2.0) / 16.0) ** 2
    return 60.0 * np.exp(-r2), x, y, z


def dose(out, bits=32, offsets="relative", scaling=True, uneven=None, **grid):
    """An RT Dose of dose_field(): frames bottom to top (reversed: top to bottom, offsets negative),
    GridFrameOffsetVector relative (first 0) or absolute z; stored = round(dose / scaling). Returns
    the grid of Gy the file holds (stored x scaling), its x, y, z."""
    gy, x, y, z = dose_field(**grid)
    top = 2 ** (bits - 1) if bits == 32 else 2 ** bits - 1
    s = float(gy.max()) / top
    stored = np.rint(gy / s).astype(np.uint32 if bits == 32 else np.uint16)
    ds = _base(RT_DOSE, "RTDOSE")
    ds.Rows, ds.Columns = len(y), len(x)
    ds.BitsAllocated = ds.BitsStored = bits
    ds.HighBit, ds.PixelRepresentation = bits - 1, 0
    ds.NumberOfFrames = len(z)
    ds.FrameIncrementPointer = 0x3004000C
    ds.PixelSpacing = [float(y[1] - y[0]), float(x[1] - x[0])]  # rows \ columns
    ds.ImageOrientationPatient = [1, 0, 0, 0, 1, 0]
    ds.DoseUnits, ds.DoseType, ds.DoseSummationType = "GY", "PHYSICAL", "PLAN"
    ds.ApprovalStatus, ds.ReviewerName = "APPROVED", PEOPLE["ReviewerName"]  # RT Approval (C.8.8.16)
    if scaling:
        ds.DoseGridScaling = "%.10g" % s
    frames = stored
    zs = list(z)
    if offsets == "reversed":
        frames, zs = stored[::-1], zs[::-1]
    ds.ImagePositionPatient = [float(x[0]), float(y[0]), float(zs[0])]
    off = [v - zs[0] for v in zs] if offsets != "absolute" else list(zs)
    if uneven is not None:
        off[uneven] += 0.4 * (z[1] - z[0])
    ds.GridFrameOffsetVector = ["%.6g" % v for v in off]
    ds.PixelData = np.ascontiguousarray(frames).astype("<u%d" % (bits // 8)).tobytes()
    _save(ds, out)
    return stored.astype(np.float64) * float("%.10g" % s), x, y, z


def dose_oriented(out, orient=(0, 1, 0, 0, 0, -1), shape=(30, 36, 40), spacing=(2.5, 2.0, 3.0),
                  corner=(48.0, -40.0, 45.0), bits=32):
    """An RT Dose whose planes are not axial: ImageOrientationPatient orient (by default sagittal,
    its columns running down, so the planes' normal r x c is -x and GridFrameOffsetVector's
    offsets, relative, run along it), its first frame's first sample at corner; shape is frames,
    rows, columns, spacing along the rows (r), the columns (c) and the normal. Each sample holds
    dose_field's Gaussian where the sample lies in patient coordinates. Returns the Gy the file
    holds (frames, rows, columns), the corner, the axes r, c, n and the spacing along them."""
    r, c = np.array(orient[:3], float), np.array(orient[3:], float)
    n = np.cross(r, c)
    nk, ni, nj = shape
    K, I, J = np.meshgrid(np.arange(nk), np.arange(ni), np.arange(nj), indexing="ij")
    P = [corner[a] + J * spacing[0] * r[a] + I * spacing[1] * c[a] + K * spacing[2] * n[a] for a in range(3)]
    gy = 60.0 * np.exp(-(((P[0] - 5.0) / 18.0) ** 2 + ((P[1] + 3.0) / 14.0) ** 2 + ((P[2] - 2.0) / 16.0) ** 2))
    top = 2 ** (bits - 1) if bits == 32 else 2 ** bits - 1
    sc = float("%.10g" % (float(gy.max()) / top))
    stored = np.rint(gy / sc).astype(np.uint32 if bits == 32 else np.uint16)
    ds = _base(RT_DOSE, "RTDOSE")
    ds.Rows, ds.Columns = ni, nj
    ds.BitsAllocated = ds.BitsStored = bits
    ds.HighBit, ds.PixelRepresentation = bits - 1, 0
    ds.NumberOfFrames = nk
    ds.FrameIncrementPointer = 0x3004000C
    ds.PixelSpacing = [float(spacing[1]), float(spacing[0])]  # rows \ columns
    ds.ImageOrientationPatient = [float(v) for v in orient]
    ds.ImagePositionPatient = [float(v) for v in corner]
    ds.DoseUnits, ds.DoseType, ds.DoseSummationType = "GY", "PHYSICAL", "PLAN"
    ds.DoseGridScaling = "%.10g" % sc
    ds.GridFrameOffsetVector = ["%.6g" % (k * spacing[2]) for k in range(nk)]
    ds.PixelData = stored.astype("<u%d" % (bits // 8)).tobytes()
    _save(ds, out)
    return stored.astype(np.float64) * sc, np.array(corner, float), (r, c, n), spacing


def seg_labels(shape=(24, 27, 31), spacing=(1.5, 1.25, 2.0), origin=(-20.0, -17.0, -10.0), layout=None):
    """Two segments on a grid (z, y, x): 1 a ball, 2 a box apart from it; layout "touching": the
    box a slab on the ball's top, taking the samples the ball leaves free from z = 16 up (as a label
    map they share a boundary), "overlapping": the slab from z = 14 whatever the ball holds. Each
    is in some planes alone (so frames are sparse). As 0..1 fractions: the ball's edge partial. Frames of
    27 x 31 samples: 837 bits, so a BINARY frame begins where the one before ends, mid-byte
    (PS3.5 8.1.1), not at a byte."""
    nz, ny, nx = shape
    x = origin[0] + spacing[0] * np.arange(nx)
    y = origin[1] + spacing[1] * np.arange(ny)
    z = origin[2] + spacing[2] * np.arange(nz)
    Z, Y, X = np.meshgrid(z, y, x, indexing="ij")
    r = np.sqrt((X + 2.0) ** 2 + (Y - 0.5) ** 2 + (Z - 10.0) ** 2)
    ball = np.clip(9.0 - r + 0.5, 0.0, 1.0)  # a 9 mm ball, its edge a ramp a mm wide
    box = ((np.abs(X - 12.0) <= 6) & (np.abs(Y + 5.0) <= 4) & (Z >= 18) & (Z <= 30)).astype(np.float64)
    if layout:
        slab = (np.abs(X + 2.0) <= 6) & (np.abs(Y - 0.5) <= 5) & (Z <= 30)
        box = (slab & (Z >= 16) & (ball < 0.5) if layout == "touching" else slab & (Z >= 14)).astype(np.float64)
    return {1: ball, 2: box}, x, y, z


def seg(out, fractional=False, extra_frame=None, bad_label=False, segments=2, twice=None, **grid):
    """A Segmentation of seg_labels(): a frame per segment per plane where the segment is not empty
    (shuffled). BINARY: fraction >= 0.5; FRACTIONAL: round(fraction x 200) of 200. extra_frame: a
    frame of segment 1 also at plane K (two at one place); bad_label: a frame naming segment 7;
    segments: SegmentSequence lists this many, those past 2 without frames; twice: the last of
    them numbered TWICE again. Returns the label grids the file holds (0/1 or fractions) and x,
    y, z."""
    labels, x, y, z = seg_labels(**grid)
    ds = _base(SEGMENTATION, "SEG")
    ds.Rows, ds.Columns = len(y), len(x)
    ds.SegmentationType = "FRACTIONAL" if fractional else "BINARY"
    if fractional:
        ds.SegmentationFractionalType, ds.MaximumFractionalValue = "PROBABILITY", 200
        ds.BitsAllocated = ds.BitsStored = 8
        ds.HighBit = 7
    else:
        ds.BitsAllocated = ds.BitsStored = 1
        ds.HighBit = 0
    ds.PixelRepresentation = 0
    ds.SegmentSequence = Sequence([_item(SegmentNumber=1, SegmentLabel="Ball", SegmentAlgorithmType="MANUAL"),
                                   _item(SegmentNumber=2, SegmentLabel="Box", SegmentAlgorithmType="MANUAL")] +
                                  [_item(SegmentNumber=k, SegmentLabel="S%d" % k, SegmentAlgorithmType="MANUAL")
                                   for k in range(3, segments + 1)])
    if twice is not None:
        ds.SegmentSequence[-1].SegmentNumber = twice
    ds.ContentCreatorName = PEOPLE["ContentCreatorName"]  # Type 2 in every Segmentation (C.8.20.2)
    ds.SharedFunctionalGroupsSequence = Sequence([_item(
        PlaneOrientationSequence=Sequence([_item(ImageOrientationPatient=[1, 0, 0, 0, 1, 0])]),
        PixelMeasuresSequence=Sequence([_item(PixelSpacing=[float(y[1] - y[0]), float(x[1] - x[0])],
                                              SliceThickness=float(z[1] - z[0]),
                                              SpacingBetweenSlices=float(z[1] - z[0]))]))])
    held = {}
    frames = []
    for n, lab in labels.items():
        v = np.rint(lab * 200) / 200 if fractional else (lab >= 0.5).astype(np.float64)
        held[n] = v
        for k in range(len(z)):
            if v[k].any():
                frames.append((n, k, v[k]))
    if extra_frame is not None:
        frames.append((1, extra_frame, held[1][extra_frame]))
    if bad_label:
        frames.append((7, frames[0][1], frames[0][2]))
    random.Random(4).shuffle(frames)
    per, pix = [], []
    for n, k, plane in frames:
        per.append(_item(PlanePositionSequence=Sequence([_item(ImagePositionPatient=[float(x[0]), float(y[0]), float(z[k])])]),
                         SegmentIdentificationSequence=Sequence([_item(ReferencedSegmentNumber=n)])))
        pix.append(np.rint(plane * 200).astype(np.uint8) if fractional else (plane > 0).astype(np.uint8))
    ds.PerFrameFunctionalGroupsSequence = Sequence(per)
    ds.NumberOfFrames = len(frames)
    flat = np.concatenate([p.ravel() for p in pix])
    if fractional:
        ds.PixelData = flat.tobytes()
    else:  # PS3.5 8.1.1: frames packed bit after bit, no padding between them, lowest bit first
        packed = np.packbits(flat, bitorder="little").tobytes()
        ds.PixelData = packed + (b"\0" if len(packed) % 2 else b"")
    _save(ds, out)
    return held, x, y, z


def seg_frames(out, n, placed=False, rows=4, cols=4):
    """A BINARY Segmentation of one segment in n frames of rows x cols (NumberOfFrames n, an item
    of PerFrameFunctionalGroupsSequence each). placed: each item holds its frame's position, 1 mm
    along z from the one before, and the frames hold a column of 1s inside a border of 0s; else
    every item is empty, every group shared, so every frame lies in one plane. Returns the label
    grid (n, rows, cols) and x, y, z."""
    ds = _base(SEGMENTATION, "SEG")
    ds.Rows, ds.Columns = rows, cols
    ds.SegmentationType = "BINARY"
    ds.BitsAllocated = ds.BitsStored = 1
    ds.HighBit, ds.PixelRepresentation = 0, 0
    ds.ContentCreatorName = PEOPLE["ContentCreatorName"]
    ds.SegmentSequence = Sequence([_item(SegmentNumber=1, SegmentLabel="Column", SegmentAlgorithmType="MANUAL")])
    shared = _item(PlaneOrientationSequence=Sequence([_item(ImageOrientationPatient=[1, 0, 0, 0, 1, 0])]),
                   PixelMeasuresSequence=Sequence([_item(PixelSpacing=[1.0, 1.0], SliceThickness=1.0)]),
                   SegmentIdentificationSequence=Sequence([_item(ReferencedSegmentNumber=1)]))
    if not placed:
        shared.PlanePositionSequence = Sequence([_item(ImagePositionPatient=[0.0, 0.0, 0.0])])
    ds.SharedFunctionalGroupsSequence = Sequence([shared])
    ds.PerFrameFunctionalGroupsSequence = Sequence(
        [_item(PlanePositionSequence=Sequence([_item(ImagePositionPatient=[0, 0, k])])) if placed else Dataset()
         for k in range(n)])
    ds.NumberOfFrames = n
    frame = np.zeros((rows, cols), np.uint8)
    frame[1:-1, 1:-1] = 1 if placed else 0
    grid = np.broadcast_to(frame, (n, rows, cols))
    packed = np.packbits(np.ascontiguousarray(grid).ravel(), bitorder="little").tobytes()
    ds.PixelData = packed + (b"\0" if len(packed) % 2 else b"")
    _save(ds, out)
    return grid, np.arange(cols, dtype=float), np.arange(rows, dtype=float), np.arange(n, dtype=float)


def fragments_added(src, out, n, frame=None):
    """src, an encapsulated image of one fragment a frame (dcmtk's tools' default), with n empty
    fragments (items of length 0) after frame FRAME's fragment (the last frame's when None), the
    Basic Offset Table, when there is one, moved on past them. Bytes are edited, item by item."""
    b = bytearray(open(src, "rb").read())
    at = b.rfind(b"\xe0\x7f\x10\x00OB\0\0\xff\xff\xff\xff")  # (7FE0,0010) OB, undefined length
    items, k = [], b.find(b"\xfe\xff\x00\xe0", at)
    while b[k:k + 4] == b"\xfe\xff\x00\xe0":
        items.append(k)
        k += 8 + int.from_bytes(b[k + 4:k + 8], "little")
    frames = len(items) - 1
    bot = int.from_bytes(b[items[0] + 4:items[0] + 8], "little")
    if b[k:k + 4] != b"\xfe\xff\xdd\xe0" or bot not in (0, 4 * frames):
        raise ValueError("%s: not one fragment a frame after an offset table" % src)
    f = frames - 1 if frame is None else frame
    for i in range(f + 1, frames if bot else 0):  # the frames after the new fragments begin 8 n later
        o = items[0] + 8 + 4 * i
        b[o:o + 4] = (int.from_bytes(b[o:o + 4], "little") + 8 * n).to_bytes(4, "little")
    cut = items[f + 2] if f + 2 < len(items) else k
    open(out, "wb").write(bytes(b[:cut]) + b"\xfe\xff\x00\xe0\0\0\0\0" * n + bytes(b[cut:]))


def _j2k_stream(px, rows, cols, bits, tiles=False):
    """One frame's samples (unsigned) as a lossless JPEG 2000 codestream made by opj_compress."""
    import subprocess
    import tempfile
    with tempfile.TemporaryDirectory() as tmp:
        pgm, cs = os.path.join(tmp, "s.pgm"), os.path.join(tmp, "s.j2k")
        with open(pgm, "wb") as f:
            f.write(b"P5\n%d %d\n%d\n" % (cols, rows, (1 << bits) - 1) + np.asarray(px, dtype=">u2").tobytes())
        cmd = ["opj_compress", "-i", pgm, "-o", cs, "-n", "3"] + (["-t", "32,32"] if tiles else [])
        subprocess.run(cmd, check=True, capture_output=True)
        return open(cs, "rb").read()


def j2k_frames(path, out):
    """A multi-frame image (unsigned samples, uncompressed) with each frame as a JPEG 2000 codestream of
    its own (one fragment a frame)."""
    from pydicom.encaps import encapsulate
    ds = pydicom.dcmread(path)
    n, rows, cols = int(ds.NumberOfFrames), int(ds.Rows), int(ds.Columns)
    px = np.frombuffer(ds.PixelData, dtype="<u2").reshape(n, rows, cols)
    ds.PixelData = encapsulate([_j2k_stream(px[k], rows, cols, int(ds.BitsStored)) for k in range(n)])
    ds["PixelData"].VR = "OB"
    ds.file_meta.TransferSyntaxUID = "1.2.840.10008.1.2.4.90"
    ds.is_little_endian, ds.is_implicit_VR = True, False
    ds.save_as(out, write_like_original=False)


def j2k(series_dir, out_dir, tiles=False):
    """The classic series in series_dir with each slice's pixel data as JPEG 2000 (lossless, 5/3:
    transfer syntax 1.2.840.10008.1.2.4.90), its codestream made by OpenJPEG's opj_compress from the
    slice's samples (unsigned: the shared series' are 12 bits in 16), encapsulated by pydicom."""
    from pydicom.encaps import encapsulate
    os.makedirs(out_dir, exist_ok=True)
    for name in sorted(os.listdir(series_dir)):
        ds = pydicom.dcmread(os.path.join(series_dir, name))
        ds.PixelData = encapsulate([_j2k_stream(ds.pixel_array, ds.Rows, ds.Columns, ds.BitsStored, tiles)])
        ds["PixelData"].VR = "OB"
        ds.file_meta.TransferSyntaxUID = "1.2.840.10008.1.2.4.90"
        ds.is_little_endian, ds.is_implicit_VR = True, False
        ds.save_as(os.path.join(out_dir, name), write_like_original=False)


RT_STRUCTURE_SET = "1.2.840.10008.5.1.4.1.1.481.3"


def rtstruct_rois(slices=(0.0, 3.0, 6.0)):
    """What rtstruct() draws: name -> (the contour of each slice, its area), as a planning system
    draws a couch (4 points), an L-shaped block (6), a box with points midway along its edges (8),
    an octagon (8, short of corners) and an outlined organ (an ellipse of 72 points)."""
    import math
    ell = [(60 * math.cos(2 * math.pi * k / 72), 40 * math.sin(2 * math.pi * k / 72)) for k in range(72)]
    octagon = [(30 * math.cos(2 * math.pi * k / 8), 30 * math.sin(2 * math.pi * k / 8)) for k in range(8)]
    rois = {
        "Couch": ([(-200, -150), (200, -150), (200, 150), (-200, 150)], 400 * 300),
        "Block": ([(0, 0), (60, 0), (60, 20), (20, 20), (20, 50), (0, 50)], 60 * 20 + 20 * 30),
        "Box": ([(0, 0), (25, 0), (50, 0), (50, 25), (50, 50), (25, 50), (0, 50), (0, 25)], 50 * 50),
        "Octagon": (octagon, 2 * math.sqrt(2) * 30 * 30),
        "Organ": (ell, math.pi * 60 * 40),
    }
    return rois, slices


def rtstruct(out):
    """An RT Structure Set (C.8.8.5, C.8.8.6) of rtstruct_rois(), each ROI on three slices."""
    rois, slices = rtstruct_rois()
    ds = _base(RT_STRUCTURE_SET, "RTSTRUCT")
    del ds.SamplesPerPixel, ds.PhotometricInterpretation
    ds.StructureSetLabel = "sparse"
    ds.ReferencedFrameOfReferenceSequence = Sequence([_item(FrameOfReferenceUID=ds.FrameOfReferenceUID)])
    ds.StructureSetROISequence = Sequence(
        [_item(ROINumber=k + 1, ReferencedFrameOfReferenceUID=ds.FrameOfReferenceUID, ROIName=name,
               ROIGenerationAlgorithm="MANUAL") for k, name in enumerate(rois)])
    ds.ROIContourSequence = Sequence(
        [_item(ReferencedROINumber=k + 1, ROIDisplayColor=[255, 0, 0], ContourSequence=Sequence(
            [_item(ContourGeometricType="CLOSED_PLANAR", NumberOfContourPoints=len(pts),
                   ContourData=[f"{v:.4f}" for x, y in pts for v in (x, y, z)]) for z in slices]))
         for k, (name, (pts, _)) in enumerate(rois.items())])
    ds.RTROIObservationsSequence = Sequence(
        [_item(ObservationNumber=k + 1, ReferencedROINumber=k + 1, RTROIInterpretedType="ORGAN", ROIInterpreter="")
         for k in range(len(rois))])
    _save(ds, out)


if __name__ == "__main__":
    what, args = sys.argv[1], sys.argv[2:]
    opts = dict(a.split("=", 1) for a in args if "=" in a)
    flags = [a for a in args if "=" not in a]
    if what == "enhanced":
        enhanced(flags[0], flags[1], "shared-rescale" in flags, "shuffle" in flags)
    elif what == "dose":
        dose(flags[0], int(opts.get("bits", 32)), opts.get("offsets", "relative"), opts.get("scaling") != "no",
             int(opts["uneven"]) if "uneven" in opts else None)
    elif what == "seg":
        seg(flags[0], opts.get("type") == "fractional")
    elif what == "rtstruct":
        rtstruct(flags[0])
    elif what == "j2k":
        j2k(flags[0], flags[1], "tiles" in flags)
    elif what == "j2k-frames":
        j2k_frames(flags[0], flags[1])
    elif what == "counts":
        import subprocess
        import tempfile
        out = flags[1]
        seg_frames(os.path.join(out, "hang_per_frame_items"), 30000, rows=1, cols=1)  # 8 bytes an item
        seg(os.path.join(out, "hang_segments"), shape=(10, 9, 11), spacing=(3.0, 2.5, 4.0))
        ds = pydicom.dcmread(os.path.join(out, "hang_segments"))  # 13 000 segments of 18 bytes
        ds.SegmentSequence = Sequence(list(ds.SegmentSequence) + [_item(SegmentNumber=k) for k in range(3, 13001)])
        _save(ds, os.path.join(out, "hang_segments"))
        with tempfile.TemporaryDirectory() as tmp:
            enhanced(flags[0], os.path.join(tmp, "ect"), shuffle=True)
            subprocess.run(["dcmcjpls", os.path.join(tmp, "ect"), os.path.join(tmp, "jls")], check=True)
            fragments_added(os.path.join(tmp, "jls"), os.path.join(out, "hang_fragments"), 30000)
    elif what == "seeds":
        enhanced(flags[0], os.path.join(flags[1], "enhanced_ct"), shuffle=True)
        small = dict(shape=(5, 6, 8), spacing=(9.0, 8.0, 10.0), origin=(-30.0, -25.0, -20.0))
        dose(os.path.join(flags[1], "dose16"), 16, **small)
        dose(os.path.join(flags[1], "dose32_absolute"), 32, "absolute", **small)
        small = dict(shape=(10, 9, 11), spacing=(3.0, 2.5, 4.0))  # 99 bits a frame: frames mid-byte
        seg(os.path.join(flags[1], "seg_binary"), **small)
        seg(os.path.join(flags[1], "seg_fractional"), True, **small)
    else:
        sys.exit(__doc__)
