"""plastimatch_volumes.py - each ROI's volume as plastimatch reads an RT Structure Set: every contour
rasterised and filled (or'd, plastimatch's default; --xor: xor'd, even-odd) on a grid of 0.5 mm in
x and y whose z slabs are the contours' planes, H mm apart (the structure set's own spacing).
Prints NAME<TAB>MM3 a line. Usage: plastimatch_volumes.py RS.dcm H [--xor]. Debian's python3
(pydicom, numpy)."""
import os
import subprocess
import sys
import tempfile

import numpy as np
import pydicom

ds = pydicom.dcmread(sys.argv[1])
h = float(sys.argv[2])
zs, xs, ys = [], [], []
for r in ds.ROIContourSequence:
    for c in getattr(r, "ContourSequence", []):
        d = np.array(c.ContourData, float).reshape(-1, 3)
        zs.append(d[0, 2])
        xs += [d[:, 0].min(), d[:, 0].max()]
        ys += [d[:, 1].min(), d[:, 1].max()]
sp = 0.5
ox, oy, oz = min(xs) - 2, min(ys) - 2, min(zs)
# plastimatch without a reference image leaves out the top plane (contours README): the grid is given
dim = (int((max(xs) - ox + 2) / sp) + 1, int((max(ys) - oy + 2) / sp) + 1, int(round((max(zs) - oz) / h)) + 1)
out = tempfile.mkdtemp()
subprocess.run(["plastimatch", "convert", "--input", sys.argv[1], "--output-prefix", out, "--prefix-format", "nrrd",
                "--output-ss-list", out + "/list.txt", "--origin", "%g %g %g" % (ox, oy, oz),
                "--spacing", "%g %g %g" % (sp, sp, h), "--dim", "%d %d %d" % dim]
               + (["--xor-contours"] if "--xor" in sys.argv else []),
               check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
for line in open(out + "/list.txt"):
    index, _, name = line.rstrip("\n").split("|", 2)
    if int(index) < 0:  # an ROI without contours
        continue
    header, data = open(os.path.join(out, name + ".nrrd"), "rb").read().split(b"\n\n", 1)
    if b"encoding: gzip" in header:
        import gzip
        data = gzip.decompress(data)
    print("%s\t%.1f" % (name, np.count_nonzero(np.frombuffer(data, np.uint8)) * sp * sp * h))
    os.remove(os.path.join(out, name + ".nrrd"))
os.remove(out + "/list.txt")
os.rmdir(out)
