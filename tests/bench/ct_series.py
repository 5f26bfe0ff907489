#!/usr/bin/python3
"""ct_series.py N OUT_DIR: a CT series of N slices of 256 x 256 (the shared 64 x 64 x 27 CT head
upsampled 4x in-plane and cycled along z), each a Part 10 file with its own UIDs, for the DICOM
network's bench (tests/bench/dicom_net.sh): a series the size a PACS sends, made from real data.
Debian's python3-pydicom and numpy (/usr/bin/python3)."""
import os
import sys

import numpy as np
import pydicom
from pydicom.uid import generate_uid

n, out = int(sys.argv[1]), sys.argv[2]
src = os.path.join(os.environ.get("SURFD_DATA", os.path.join(os.path.dirname(__file__), "..", "..", "..", "shared", "data")),
                   "volumes", "dicom_ct_head_64x64x27")
slices = sorted((pydicom.dcmread(os.path.join(src, f)) for f in os.listdir(src) if f.endswith(".dcm")),
                key=lambda d: float(d.ImagePositionPatient[2]))
study, series, frame = generate_uid(), generate_uid(), generate_uid()
os.makedirs(out, exist_ok=True)
for k in range(n):
    d = slices[k % len(slices)].copy()
    pix = np.kron(d.pixel_array, np.ones((4, 4), dtype=d.pixel_array.dtype))
    d.Rows, d.Columns = pix.shape
    d.PixelSpacing = [float(d.PixelSpacing[0]) / 4, float(d.PixelSpacing[1]) / 4]
    d.ImagePositionPatient = [float(d.ImagePositionPatient[0]), float(d.ImagePositionPatient[1]), 1.25 * k]
    d.SliceThickness = 1.25
    d.InstanceNumber = k + 1
    d.StudyInstanceUID, d.SeriesInstanceUID, d.FrameOfReferenceUID = study, series, frame
    d.SOPInstanceUID = d.file_meta.MediaStorageSOPInstanceUID = generate_uid()
    d.PixelData = pix.tobytes()
    d.save_as(os.path.join(out, "IM%04d.dcm" % (k + 1)), write_like_original=False)
print(study, series)
