#!/bin/sh
# Multi-frame DICOM over POST /isosurface (issue 47: 4), on files tests/tools/dicom_write.py makes
# with pydicom: an Enhanced CT of the shared series (frames shuffled, placed by their functional
# groups, each frame's own intercept) gives the classic series' mesh to the bit, uncompressed and as
# dcmtk's tools compress it (RLE, JPEG lossless, JPEG-LS, fragments split with and without an
# offset table); an RT Dose's 20 Gy isodose is closed, in patient coordinates, and within 2 % of
# VTK's Flying Edges on the same grid scaled to Gy (16 and 32 bits, relative, absolute and reversed
# GridFrameOffsetVector, RLE, a sagittal dose whose offsets run along -x); a Segmentation's segment
# (binary and fractional, sparse frames of 27 x 31, a binary frame beginning mid-byte) gives the
# mesh its label grid gives as raw samples; counts an object sets are walked once (2^18 per-frame
# items, 65 536 offsets, 65 535 segments: they took minutes) and fragments are capped a frame; the
# stored uploads hold no patient's or staff's names; and every bad input (no DoseGridScaling,
# uneven frames, truncated frames, a codec's garbage, a label out of range, two frames of a
# segment at one place, several segments and no ?segment, two segments of one number, a
# multi-frame image among a series' parts, over the frame cap, over the fragment cap) is refused
# with its pointer, the daemon up. surfctl and the Python client post the same files. No check is
# timed: the old figures are in the commit that walked the counts once.
. "$(dirname "$0")/lib.inc"
DD="${SURFD_DATA:-../shared/data}/volumes/dicom_ct_head_64x64x27"
[ -d "$DD" ] || { bad "../shared/data/volumes not found"; checks_done; exit 1; }
PY=/usr/bin/python3 # Debian's: pydicom, numpy and VTK
$PY -c "import pydicom, numpy, vtk" 2>/dev/null || { bad "python3-pydicom, python3-numpy or python3-vtk9 is missing (deploy/install-deps.sh installs them)"; checks_done; exit 1; }
command -v dcmcjpls >/dev/null || { bad "dcmtk's tools are not installed (deploy/install-deps.sh installs them)"; checks_done; exit 1; }
start_daemon "$T/d" --threads 2 || exit 1
export SURFD_URL="$URL"
C=build/surfctl

# the files, and the Flying Edges figures of each dose on its grid in Gy (fe_NAME.json)
$PY - "$DD" "$T" <<'PY' || bad "the test files could not be written"
import json, sys
sys.path.insert(0, "tests/tools")
import numpy as np
import pydicom
import vtk
from vtk.util import numpy_support
import dicom_write as dw
dd, t = sys.argv[1], sys.argv[2]
dw.enhanced(dd, t + "/ect.dcm", shuffle=True)
dw.enhanced(dd, t + "/ect_shared.dcm", shared_rescale=True)

def flying_edges(name, gy, x, y, z, iso=20.0, corner=None, axes=None):
    """Flying Edges' isodose of gy (z, y, x) on its grid: at x, y, z; or, oriented, its columns,
    rows and frames x, y, z apart (spacings) along axes r, c, n from corner, each point placed so
    (the volume a rotation keeps)."""
    img = vtk.vtkImageData()
    img.SetDimensions(gy.shape[2], gy.shape[1], gy.shape[0])
    if axes is None:
        img.SetSpacing(x[1] - x[0], y[1] - y[0], z[1] - z[0])
        img.SetOrigin(x[0], y[0], z[0])
    else:
        img.SetSpacing(x, y, z)
    img.GetPointData().SetScalars(numpy_support.numpy_to_vtk(np.ascontiguousarray(gy, dtype=np.float32).ravel(), deep=1))
    fe = vtk.vtkFlyingEdges3D()
    fe.SetInputData(img)
    fe.SetValue(0, iso)
    fe.Update()
    mass = vtk.vtkMassProperties()
    mass.SetInputConnection(fe.GetOutputPort())
    mass.Update()
    p = numpy_support.vtk_to_numpy(fe.GetOutput().GetPoints().GetData()).astype(np.float64)
    if axes is not None:
        p = corner + p[:, :1] * axes[0] + p[:, 1:2] * axes[1] + p[:, 2:3] * axes[2]
    json.dump({"volume": mass.GetVolume(), "bounds": [p.min(0).tolist(), p.max(0).tolist()]}, open(t + "/fe_" + name + ".json", "w"))

flying_edges("rd32", *dw.dose(t + "/rd32.dcm", 32))
flying_edges("rd16", *dw.dose(t + "/rd16.dcm", 16))
dw.dose(t + "/rd_abs.dcm", 32, "absolute")
dw.dose(t + "/rd_rev.dcm", 32, "reversed")
gy, corner, axes, sp = dw.dose_oriented(t + "/rd_sag.dcm")   # sagittal: offsets along -x
flying_edges("rd_sag", gy, *sp, corner=corner, axes=axes)
dw.dose(t + "/rd_noscale.dcm", 32, scaling=False)
dw.dose(t + "/rd_uneven.dcm", 32, uneven=12)
d = pydicom.dcmread(t + "/rd32.dcm")                     # frames cut short: the element says so itself
d.PixelData = d.PixelData[: len(d.PixelData) * 2 // 3]
d.save_as(t + "/rd_short.dcm")
d = pydicom.dcmread(t + "/rd32.dcm")                     # 2^31 samples declared in some kilobytes
d.Rows, d.Columns, d.NumberOfFrames = 4096, 4096, 200
d.GridFrameOffsetVector = list(range(200))
d.PixelData = b"\0" * 64
d.save_as(t + "/rd_huge.dcm")
d = pydicom.dcmread(t + "/rd32.dcm")                     # NumberOfFrames past the cap (2^18)
d.NumberOfFrames = (1 << 18) + 1
d.save_as(t + "/rd_over.dcm")
d = pydicom.dcmread(t + "/rd32.dcm")                     # 2^16 frames of 2 x 2, 30 Gy in frames 100 to 200, its
n = 1 << 16                                              # offsets 2^16 values of text (implicit VR: over 64 KB)
d.Rows, d.Columns, d.NumberOfFrames = 2, 2, n
d.ImagePositionPatient = [0.0, 0.0, 0.0]
d.GridFrameOffsetVector = [str(k) for k in range(n)]
v = np.zeros((n, 4), "<u4")
v[100:201] = int(round(30 / float(d.DoseGridScaling)))
d.PixelData = v.tobytes()
d.file_meta.TransferSyntaxUID = pydicom.uid.ImplicitVRLittleEndian
d.is_implicit_VR = True
d.save_as(t + "/rd_frames.dcm", write_like_original=False)
d = pydicom.dcmread(t + "/rd32.dcm")                     # a dose of one plane
d.NumberOfFrames, d.GridFrameOffsetVector = 1, [0]
d.PixelData = d.PixelData[: d.Rows * d.Columns * 4]
d.save_as(t + "/rd_one.dcm")
# the segmentations, and each segment's label grid as raw samples with its layout
for name, frac in (("seg", False), ("segf", True)):
    held, x, y, z = dw.seg(t + "/" + name + ".dcm", frac)
    for n, v in held.items():
        zs = [k for k in range(len(z)) if v[k].any() or any(h[k].any() for h in held.values())]
        k0, k1 = min(zs), max(zs)
        grid = v[k0:k1 + 1]
        open("%s/%s%d.raw" % (t, name, n), "wb").write(np.ascontiguousarray(grid, dtype=np.float32 if frac else np.uint8).tobytes())
        open("%s/%s%d.q" % (t, name, n), "w").write("dims=%d,%d,%d&type=%s&spacing=%g,%g,%g&origin=%g,%g,%g" % (
            len(x), len(y), k1 - k0 + 1, "float32" if frac else "uint8", x[1] - x[0], y[1] - y[0], z[1] - z[0],
            x[0], y[0], z[k0]))
        if frac:  # as a label map's label: where its fraction is over half
            open("%s/%s%d_half.raw" % (t, name, n), "wb").write(np.ascontiguousarray(grid > 0.5, dtype=np.uint8).tobytes())
            open("%s/%s%d_half.q" % (t, name, n), "w").write(open("%s/%s%d.q" % (t, name, n)).read().replace("float32", "uint8"))
# a Segmentation whose segments touch without overlapping, and its label map (1 the ball, 2 the slab)
held, x, y, z = dw.seg(t + "/seg_apart.dcm", layout="touching")
dw.seg(t + "/seg_overlap.dcm", layout="overlapping")
zs = [k for k in range(len(z)) if any(h[k].any() for h in held.values())]
k0, k1 = min(zs), max(zs)
lab = (held[1] + 2 * held[2])[k0:k1 + 1]
assert lab.max() == 2 and not (held[1] * held[2]).any()
open(t + "/seg_apart.raw", "wb").write(np.ascontiguousarray(lab, dtype=np.uint16).tobytes())
open(t + "/seg_apart.q", "w").write("dims=%d,%d,%d&type=uint16&spacing=%g,%g,%g&origin=%g,%g,%g" % (
    len(x), len(y), k1 - k0 + 1, x[1] - x[0], y[1] - y[0], z[1] - z[0], x[0], y[0], z[k0]))
dw.seg(t + "/seg_badlabel.dcm", bad_label=True)
dw.seg(t + "/seg_twice.dcm", extra_frame=8)
# counts an object sets, each walked once: 2^18 empty per-frame items (every frame in one plane),
# 2^14 placed ones (a column 2^14 frames tall), 65 535 segments (and the last renumbered 3)
dw.seg_frames(t + "/seg_items.dcm", 1 << 18)
grid, x, y, z = dw.seg_frames(t + "/seg_column.dcm", 1 << 14, placed=True)
open(t + "/seg_column.raw", "wb").write(np.ascontiguousarray(grid, dtype=np.uint8).tobytes())
dw.seg(t + "/seg_many.dcm", segments=65535)
b = bytearray(open(t + "/seg_many.dcm", "rb").read())
at = b.rfind(b"\x62\x00\x04\x00US\x02\x00")          # the last SegmentNumber (0062,0004)
b[at + 8:at + 10] = (3).to_bytes(2, "little")
open(t + "/seg_many_twice.dcm", "wb").write(b)
open(t + "/people", "w").write("\n".join(dw.PEOPLE.values()) + "\n")   # the names every file carries
PY
# ... and fragments: the Enhanced CT as JPEG-LS (an offset table, or none) with empty fragments
dcmcjpls "$T/ect.dcm" "$T/ect_jls.dcm" && dcmcjpls -ot "$T/ect.dcm" "$T/ect_jls_ot.dcm" || bad "dcmcjpls ect"
$PY - "$T" <<'PY' || bad "the fragmented files could not be written"
import sys
sys.path.insert(0, "tests/tools")
import dicom_write as dw
t = sys.argv[1]
dw.fragments_added(t + "/ect_jls.dcm", t + "/ect_frags.dcm", 100000)         # 100 000 after the last frame
dw.fragments_added(t + "/ect_jls_ot.dcm", t + "/ect_frags_f3.dcm", 40, 3)    # 41 fragments in frame 3
dw.fragments_added(t + "/ect_jls.dcm", t + "/ect_frags_ok.dcm", 20, 3)       # 21: within the cap
PY

# post FILE QUERY: FILE as the body (application/dicom); the answer in $T/body
post() { status POST "/isosurface?$2" -H 'Content-Type: application/dicom' --data-binary @"$1"; }
series() { parts=""; for f in "$1"/*; do parts="$parts -F slice=@$f"; done; status POST "/isosurface?iso=226.5" $parts; } # shellcheck disable=SC2086
# same A B: two model resources with the same triangles, volume and bounds (to the bit)
same() { python3 -c "
import json, sys
a, b = json.load(open(sys.argv[1])), json.load(open(sys.argv[2]))
sys.exit(0 if a['triangles'] == b['triangles'] and a['volume_mm3'] == b['volume_mm3'] and a['bounds'] == b['bounds'] else 1)" "$1" "$2"; }
closed() { python3 -c "
import json, sys
a = json.load(open(sys.argv[1]))
sys.exit(0 if a['triangles'] > 0 and a['boundary_edges'] == 0 and a['nonmanifold_edges'] == 0 else 1)" "$1"; }
pointer() { grep -q "\"pointer\":\"$1\"" "$T/body"; }

# ---- Enhanced CT ----
code=$(series "$DD"); cp "$T/body" "$T/classic.json"
check "the classic series: 201" '[ "$code" = 201 ]'
code=$(post "$T/ect.dcm" "iso=226.5"); cp "$T/body" "$T/ect.json"
check "an Enhanced CT of the series (frames shuffled, each frame's own intercept and stored values: one frame's rescale for all would miss) as the body: the series' mesh to the bit" '[ "$code" = 201 ] && same "$T/ect.json" "$T/classic.json"'
code=$(status POST "/isosurface?iso=226.5" -F "image=@$T/ect_shared.dcm")
check "... with its rescale shared, as a one-part multipart series: the same" '[ "$code" = 201 ] && same "$T/body" "$T/classic.json"'
code=$(status POST "/isosurface?iso=226.5" -H 'Content-Type: application/octet-stream' --data-binary @"$T/ect.dcm")
check "... posted as octet-stream without dims: read as the DICOM file it is" '[ "$code" = 201 ] && same "$T/body" "$T/classic.json"'
for how in "dcmcrle" "dcmcjpeg" "dcmcjpls" "dcmcjpls +fs 1" "dcmcjpls +fs 1 -ot"; do
    f="$T/ect_$(echo "$how" | tr -d ' +-').dcm"
    $how "$T/ect.dcm" "$f" || bad "$how"
    code=$(post "$f" "iso=226.5")
    check "the Enhanced CT compressed by $how: the same mesh, each frame decoded alone" '[ "$code" = 201 ] && same "$T/body" "$T/classic.json"'
done
if command -v opj_compress >/dev/null; then
    $PY tests/tools/dicom_write.py j2k-frames "$T/ect.dcm" "$T/ect_j2k.dcm"
    code=$(post "$T/ect_j2k.dcm" "iso=226.5")
    check "the Enhanced CT's frames each JPEG 2000 (opj_compress; OpenJPEG decodes them): the same mesh" '[ "$code" = 201 ] && same "$T/body" "$T/classic.json"'
else
    bad "opj_compress (libopenjp2-tools) is missing (deploy/install-deps.sh installs it)"
fi
python3 -c "
import sys
d = bytearray(open(sys.argv[1], 'rb').read())
at = [i for i in range(len(d) - 1) if d[i] == 0xff and d[i + 1] == 0xd8][5]   # frame 5's JPEG-LS stream
for k in range(at + 60, at + 600, 5): d[k] ^= 0x5a
open(sys.argv[2], 'wb').write(d)" "$T/ect_dcmcjpls.dcm" "$T/ect_garbage.dcm"
code=$(post "$T/ect_garbage.dcm" "iso=226.5")
check "a frame whose JPEG-LS stream is garbage: 422 at that frame, saying it does not decode" '[ "$code" = 422 ] && is_problem 422 && grep -q "does not decode" "$T/body" && grep -q "\"pointer\":\"/parts/0/frames/" "$T/body"'
python3 -c "
import struct, sys
d = bytearray(open(sys.argv[1], 'rb').read())
at = d.find(b'\xfe\xff\x00\xe0', d.rfind(b'\xe0\x7f\x10\x00')) # the offset table's item
at = d.find(b'\xfe\xff\x00\xe0', at + 8)                       # frame 0's fragment: its RLE header
d[at + 8 + 4:at + 8 + 8] = struct.pack('<I', 1 << 30)          # a stripe 1 GB past the fragment
open(sys.argv[2], 'wb').write(d)" "$T/ect_dcmcrle.dcm" "$T/ect_rlebad.dcm"
code=$(post "$T/ect_rlebad.dcm" "iso=226.5")
check "an RLE frame whose header points past its fragment: 422 at frame 0" '[ "$code" = 422 ] && pointer "/parts/0/frames/0"'
code=$(post "$T/ect_frags.dcm" "iso=226.5")
check "the JPEG-LS Enhanced CT with 100 000 empty fragments after its last frame (913 KB; it took 27 s and was read): 422 at the part, naming the cap" '[ "$code" = 422 ] && pointer /parts/0 && grep -q "100027 fragments for 27 frames: surfd reads at most 32 a frame" "$T/body"'
code=$(post "$T/ect_frags_f3.dcm" "iso=226.5")
check "... with 40 after frame 3 and no offset table (frames by their JPEG markers): 422 at frame 3, 41 fragments" '[ "$code" = 422 ] && pointer /parts/0/frames/3 && grep -q "spans 41 fragments" "$T/body"'
code=$(post "$T/ect_frags_ok.dcm" "iso=226.5")
check "... with 20 after frame 3, the offset table moved on: within the cap, the series' mesh" '[ "$code" = 201 ] && same "$T/body" "$T/classic.json"'

# ---- RT Dose ----
# fe NAME: the model in $T/body within 2 % of Flying Edges' volume, its bounds within 0.05 mm of FE's, closed
fe() { python3 -c "
import json, sys
a, f = json.load(open(sys.argv[1])), json.load(open(sys.argv[2]))
rel = abs(a['volume_mm3'] - f['volume']) / f['volume']
near = all(abs(p - q) < 0.05 for s, r in zip(a['bounds'], f['bounds']) for p, q in zip(s, r))
print('%s: surfd %.1f mm3, Flying Edges %.1f mm3: %.3f %%' % (sys.argv[3], a['volume_mm3'], f['volume'], 100 * rel))
sys.exit(0 if rel < 0.02 and near and a['boundary_edges'] == 0 else 1)" "$T/body" "$T/fe_$1.json" "$1"; }
code=$(post "$T/rd32.dcm" "iso=20"); cp "$T/body" "$T/rd32.json"
check "an RT Dose (32 bits) as the body, iso=20: its 20 Gy isodose, closed, within 2 % of Flying Edges, in place" '[ "$code" = 201 ] && fe rd32'
code=$(post "$T/rd16.dcm" "iso=20")
check "... of 16 bits: the same" '[ "$code" = 201 ] && fe rd16'
code=$(status POST "/isosurface?iso=20" -F "dose=@$T/rd32.dcm")
check "... as a one-part multipart series: the same model" '[ "$code" = 201 ] && same "$T/body" "$T/rd32.json"'
code=$(post "$T/rd_abs.dcm" "iso=20")
check "... its GridFrameOffsetVector absolute z (PS3.3 C.8.8.3.2): the same model" '[ "$code" = 201 ] && same "$T/body" "$T/rd32.json"'
code=$(post "$T/rd_rev.dcm" "iso=20")
check "... its frames top to bottom (offsets negative): sorted, the same model" '[ "$code" = 201 ] && same "$T/body" "$T/rd32.json"'
dcmcrle "$T/rd32.dcm" "$T/rd_rle.dcm" || bad "dcmcrle rd32"
code=$(post "$T/rd_rle.dcm" "iso=20")
check "... RLE compressed (32-bit samples, four stripes a frame): the same model" '[ "$code" = 201 ] && same "$T/body" "$T/rd32.json"'
code=$(post "$T/rd_sag.dcm" "iso=20")
check "a sagittal RT Dose (offsets along the normal -x, not z): the 20 Gy isodose within 2 % of Flying Edges on its grid placed in patient coordinates, its bounds within 0.05 mm" '[ "$code" = 201 ] && fe rd_sag'
code=$(post "$T/rd_frames.dcm" "iso=20")
check "an RT Dose of 65 536 frames, its GridFrameOffsetVector 65 536 values of text (each read once): 201, the dose where offsets 100 to 200 put it" '[ "$code" = 201 ] && python3 -c "
import json, sys
b = json.load(open(sys.argv[1]))[\"bounds\"]
sys.exit(0 if 99 <= b[0][2] <= 100 and 200 <= b[1][2] <= 201 else 1)" "$T/body"'
code=$(post "$T/rd_over.dcm" "iso=20")
check "an RT Dose whose NumberOfFrames is 2^18 + 1: 422 (over the frame cap) naming it" '[ "$code" = 422 ] && pointer /parts/0 && grep -q "NumberOfFrames is 262145: surfd reads 1 to 262144" "$T/body"'
code=$(post "$T/rd_noscale.dcm" "iso=20")
check "an RT Dose without DoseGridScaling: 422 naming it" '[ "$code" = 422 ] && grep -q DoseGridScaling "$T/body" && pointer /parts/0'
code=$(post "$T/rd_uneven.dcm" "iso=20")
check "an RT Dose with one frame out of step: 422 at that frame (not resampled)" '[ "$code" = 422 ] && pointer /parts/0/frames/12 && grep -q "uneven" "$T/body"'
code=$(post "$T/rd_short.dcm" "iso=20")
check "an RT Dose whose pixel data ends before its last frames: 422 at the first frame cut short" '[ "$code" = 422 ] && pointer /parts/0/frames/20 && grep -q "ends before" "$T/body"'
code=$(post "$T/rd_huge.dcm" "iso=20")
check "an RT Dose declaring 3.4 G samples in a few KB: 422 (over the cap) before anything is allocated" '[ "$code" = 422 ] && grep -q "samples: over" "$T/body"'
code=$(post "$T/rd_one.dcm" "iso=20")
check "an RT Dose of one plane: 422" '[ "$code" = 422 ] && grep -q "one plane" "$T/body"'
head -c 40000 "$T/rd32.dcm" >"$T/rd_cut.dcm"
code=$(post "$T/rd_cut.dcm" "iso=20")
check "an RT Dose file cut short: 400, not DICOM as it stands" '[ "$code" = 400 ] && is_problem 400'
code=$(post "$T/rd32.dcm" "iso=20&segment=1")
check "?segment on an RT Dose: 422 at ?segment" '[ "$code" = 422 ] && pointer "?segment"'
code=$(status POST "/isosurface?iso=226.5" -F "slice=@$DD/IM0001.dcm" -F "slice=@$T/ect.dcm")
check "a multi-frame image among a series' parts: 422 at its part, read alone" '[ "$code" = 422 ] && pointer /parts/1 && grep -q "read alone" "$T/body"'
code=$(status POST "/isosurface?iso=226.5" -F "slice=@$DD/IM0001.dcm")
check "one single-frame image: 422 saying a series is 2 slices or one multi-frame image" '[ "$code" = 422 ] && grep -q "multi-frame" "$T/body"'

# ---- Segmentation ----
code=$(post "$T/seg.dcm" "iso=0.5")
check "a Segmentation of 2 segments without ?segment: 422 at ?segment naming both" '[ "$code" = 422 ] && pointer "?segment" && grep -q "1 (Ball), 2 (Box)" "$T/body"'
for name in seg segf; do
    for n in 1 2; do
        code=$(status POST "/isosurface?iso=0.5&$(cat "$T/$name$n.q")" -H 'Content-Type: application/octet-stream' --data-binary @"$T/$name$n.raw")
        cp "$T/body" "$T/ref.json"
        [ "$code" = 201 ] || bad "the raw labels of $name $n: $code $(cat "$T/body")"
        code=$(post "$T/$name.dcm" "iso=0.5&segment=$n")
        cp "$T/body" "$T/$name$n.json"
        check "$name ($([ $name = seg ] && echo "binary, 1 bit, frames of 27 x 31 continuing mid-byte" || echo fractional, 8 bits of 200)) ?segment=$n (sparse frames, shuffled): the mesh its label grid gives, to the bit, closed" '[ "$code" = 201 ] && same "$T/body" "$T/ref.json" && closed "$T/body"'
    done
done
code=$(post "$T/seg.dcm" "iso=0.5&segment=3")
check "?segment=3 of a Segmentation of 1 and 2: 422 at ?segment listing them" '[ "$code" = 422 ] && pointer "?segment" && grep -q "no segment 3" "$T/body"'
code=$(post "$T/seg.dcm" "iso=0.5&segment=x")
check "?segment=x: 422" '[ "$code" = 422 ] && pointer "?segment"'
code=$(post "$T/seg_badlabel.dcm" "iso=0.5&segment=1")
check "a frame whose ReferencedSegmentNumber is no segment's (7): 422 at that frame" '[ "$code" = 422 ] && grep -q "\"pointer\":\"/parts/0/frames/[0-9]*\"" "$T/body" && grep -q "ReferencedSegmentNumber 7" "$T/body"'
code=$(post "$T/seg_twice.dcm" "iso=0.5&segment=1")
check "two frames of segment 1 at one position: 422 at one of them" '[ "$code" = 422 ] && grep -q "two frames of segment 1" "$T/body"'
code=$(post "$T/seg_twice.dcm" "iso=0.5&segment=2")
check "... while segment 2 of the same file reads" '[ "$code" = 201 ]'
# ... as a label map: ?labels=all every segment, ?label=N one (a fractional one's where it is over half)
models() { python3 -c "
import json, sys
print(','.join(m['name'] for m in json.load(open(sys.argv[1]))['models']))" "$1"; }
meshes() { python3 -c "
import json, sys, urllib.request
for m in json.load(open(sys.argv[1]))['models']:
    sys.stdout.buffer.write(urllib.request.urlopen(sys.argv[2] + m['links']['mesh']).read()[80:])" "$1" "$URL"; }
code=$(status POST "/isosurface?labels=all&$(cat "$T/seg_apart.q")" -H 'Content-Type: application/octet-stream' --data-binary @"$T/seg_apart.raw")
cp "$T/body" "$T/apart_ref.json"
[ "$code" = 201 ] || bad "the raw label map of seg_apart: $code $(cat "$T/body")"
code=$(post "$T/seg_apart.dcm" "labels=all")
check "?labels=all of a Segmentation whose segments touch: 201, a model a segment named by its SegmentLabel (?segment=N is not needed)" '[ "$code" = 201 ] && [ "$(models "$T/body")" = "Ball,Box" ]'
check "... each segment's mesh the label map's, triangle for triangle (their shared boundary included)" '[ "$(meshes "$T/body" | md5sum)" = "$(meshes "$T/apart_ref.json" | md5sum)" ] && [ "$(meshes "$T/body" | wc -c)" -gt 10000 ]'
code=$(post "$T/seg.dcm" "labels=all")
code=$(post "$T/seg_overlap.dcm" "labels=all")
check "?labels=all of a Segmentation whose segments overlap: 422 at the frame, naming both, pointing to ?segment" '[ "$code" = 422 ] && grep -q "\"pointer\":\"/parts/0/frames/[0-9]*\"" "$T/body" && grep -q "segments 1 (Ball) and 2 (Box) overlap" "$T/body" && grep -q "?segment=N" "$T/body"'
code=$(post "$T/seg.dcm" "label=2")
check "?label=2 of it: segment 2's mesh as ?segment=2 gives it, named Box" '[ "$code" = 201 ] && same "$T/body" "$T/seg2.json" && grep -q "\"name\":\"Box\"" "$T/body"'
code=$(status POST "/isosurface?iso=0.5&$(cat "$T/segf1_half.q")" -H 'Content-Type: application/octet-stream' --data-binary @"$T/segf1_half.raw")
cp "$T/body" "$T/ref.json"
code=$(post "$T/segf.dcm" "label=1")
check "?label=1 of a fractional one: the mask of its fractions over half" '[ "$code" = 201 ] && same "$T/body" "$T/ref.json"'
code=$(post "$T/seg.dcm" "label=2&segment=2")
check "?label with ?segment: 422 at ?segment" '[ "$code" = 422 ] && pointer "?segment"'
code=$(post "$T/seg.dcm" "label=3")
check "?label=3, no such segment: 422 at ?label naming the segments" '[ "$code" = 422 ] && pointer "?label" && grep -q "no segment 3" "$T/body"'
code=$(post "$T/rd32.dcm" "labels=all")
check "?labels=all of an RT Dose: 422 at ?labels, not a label map" '[ "$code" = 422 ] && pointer "?labels" && grep -q "not a label map" "$T/body"'
code=$(post "$T/seg_many.dcm" "labels=all")
check "?labels=all of 65 535 segments (it took 13.6 s to refuse without ?segment), two with frames: the two (the empty ones no labels)" '[ "$code" = 201 ] && [ "$(models "$T/body")" = "Ball,Box" ]'
code=$(post "$T/seg_items.dcm" "iso=0.5")
check "a Segmentation of 2^18 frames, every per-frame item empty (2.6 MB; it took 164 s): 422, every frame in one plane" '[ "$code" = 422 ] && grep -q "every frame lies in one plane" "$T/body"'
code=$(status POST "/isosurface?iso=0.5&dims=4,4,16384&type=uint8&spacing=1,1,1&origin=0,0,0" -H 'Content-Type: application/octet-stream' --data-binary @"$T/seg_column.raw")
cp "$T/body" "$T/ref.json"
code=$(post "$T/seg_column.dcm" "iso=0.5")
check "a Segmentation of 16 384 frames each placed by its own item: the mesh its label grid gives, to the bit" '[ "$code" = 201 ] && same "$T/body" "$T/ref.json"'
code=$(post "$T/seg_many.dcm" "iso=0.5")
check "a Segmentation of 65 535 segments (3 MB; it took 13.6 s) without ?segment: 422 at ?segment, counting and listing them" '[ "$code" = 422 ] && pointer "?segment" && grep -q "65535 segments: 1 (Ball), 2 (Box), 3 (S3)" "$T/body"'
code=$(post "$T/seg_many.dcm" "iso=0.5&segment=2")
check "... ?segment=2: the Box, as the Segmentation of 2 segments gives it" '[ "$code" = 201 ] && same "$T/body" "$T/seg2.json"'
code=$(post "$T/seg_many.dcm" "iso=0.5&segment=65535")
check "... ?segment=65535, a segment without frames: 422 at ?segment, empty" '[ "$code" = 422 ] && pointer "?segment" && grep -q "segment 65535 has no frames" "$T/body"'
code=$(post "$T/seg_many_twice.dcm" "iso=0.5&segment=2")
check "... its last segment numbered 3 again: 422 naming the number" '[ "$code" = 422 ] && pointer /parts/0 && grep -q "two segments numbered 3" "$T/body"'

# ---- patient data ----
check "the stored uploads hold no patient name or ID (blanked before they were stored)" '! grep -rqa "Doe^Jane\|SURFD-TEST-4711" "$T/d"'
# the people's names each file carries (dicom_write.py's PEOPLE: PS3.15 E.1-1 lists each)
while read -r who; do
    check "... nor $who, blanked too" '[ -n "$who" ] && ! grep -rqaF "$who" "$T/d"'
done <"$T/people"

# ---- the clients ----
$C isosurface "$T/rd32.dcm" --iso 20 -o "$T/rd.stl" >"$T/out" 2>/dev/null; rc=$?
check "surfctl isosurface DOSE.dcm --iso 20: the model curl's body gave, its STL closed" '[ $rc -eq 0 ] && same "$T/out" "$T/rd32.json" && python3 tests/tools/stl_check.py "$T/rd.stl" - >/dev/null'
$C isosurface "$T/seg.dcm" --iso 0.5 --segment 2 -o "$T/box.stl" >"$T/out" 2>/dev/null; rc=$?
cp "$T/out" "$T/body"
code=$(status POST "/isosurface?iso=0.5&$(cat "$T/seg2.q")" -H 'Content-Type: application/octet-stream' --data-binary @"$T/seg2.raw")
check "surfctl isosurface SEG.dcm --segment 2: the box" '[ $rc -eq 0 ] && same "$T/out" "$T/body"'
$C isosurface "$T/seg.dcm" --iso 0.5 -o "$T/x.stl" >"$T/out" 2>"$T/err"; rc=$?
check "surfctl without --segment: exits non-zero naming ?segment" '[ $rc -ne 0 ] && grep -q "segment" "$T/err"'
check "the Python client's isosurface(DOSE.dcm, iso=20) and (SEG.dcm, segment=1): the same models" 'PYTHONPATH=client/python python3 -c "
import json, sys, surfd
c = surfd.Client()
a = c.isosurface(sys.argv[1], iso=20); b = json.load(open(sys.argv[2]))
s = c.isosurface(sys.argv[3], iso=0.5, segment=1)
sys.exit(0 if a[\"volume_mm3\"] == b[\"volume_mm3\"] and a[\"triangles\"] == b[\"triangles\"] and s[\"triangles\"] > 0 else 1)" "$T/rd32.dcm" "$T/rd32.json" "$T/seg.dcm"'
check "the daemon up" 'alive'
finish
