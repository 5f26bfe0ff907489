#!/bin/sh
# DICOM SEG out (issue 44): ?format=seg on GET /models/{id}/mesh and GET /rtstruct?models=, and
# as=seg on POST /models/{id}/send. An isosurface of the shared CT series, stored on the node by
# C-STORE, is exported on that series' own grid: every frame's position, orientation and spacing
# the CT slice's it references, the study, frame of reference and series the CT's, its voxels
# exactly the CT's samples above the isosurface's value, and read back by surfd's own SEG reader
# into a surface of the model's volume. Models of the shared RT Structure Set, whose CT is not
# stored, are refused without ?spacing (naming the series) and exported with it, a segment each,
# labelled and coloured as the source's ROIs, each segment's voxels the model's volume. dciodvfy
# finds no errors; sent by C-STORE, DCMTK's storescp receives the SEG; bad requests are 4xx
# problems with a pointer, the caps refused before work. No patient data in the SEG.
. "$(dirname "$0")/lib.inc"
PY=/usr/bin/python3 # Debian's: pydicom, numpy
$PY -c "import pydicom, numpy" 2>/dev/null || { bad "python3-pydicom or python3-numpy is missing (deploy/install-deps.sh installs them)"; checks_done; exit 1; }
command -v dciodvfy >/dev/null && command -v storescu >/dev/null && command -v storescp >/dev/null ||
    { bad "dciodvfy (dicom3tools) or dcmtk is missing (deploy/install-deps.sh installs them)"; checks_done; exit 1; }
DD="${SURFD_DATA:-../shared/data}/volumes/dicom_ct_head_64x64x27"
RS="${SURFD_DATA:-../shared/data}/contours/dicompyler-core_example_rtss.dcm"
[ -d "$DD" ] && [ -f "$RS" ] || { bad "../shared/data not found"; checks_done; exit 1; }
DCM='Content-Type: application/dicom'
free_port() { python3 -c "import socket; s = socket.socket(); s.bind(('127.0.0.1', 0)); print(s.getsockname()[1])"; }
field() { python3 -c "import json,sys; v = json.load(open(sys.argv[1])); [v := v[k] if not isinstance(v, list) else v[int(k)] for k in sys.argv[2:]]; print(v)" "$T/body" "$@"; }
near() { python3 -c "import sys; sys.exit(0 if abs(float(sys.argv[1]) / float(sys.argv[2]) - 1) < float(sys.argv[3]) else 1)" "$@"; }
pointer() { grep -q "\"pointer\":\"$1\"" "$T/body"; }
vfy() { dciodvfy "$1" >"$T/vfy" 2>&1; grep -q "^Segmentation" "$T/vfy" && ! grep -q "^Error" "$T/vfy"; }

DP=$(free_port); SCP=$(free_port)
echo "STORESCU 127.0.0.1 11112" >"$T/peers"
mkdir -p "$T/scp"
storescp -aet TPS -od "$T/scp" +xa "$SCP" >"$T/scp.log" 2>&1 &
SCP_PID=$!
trap 'kill "$SCP_PID" 2>/dev/null; stop_daemon; rm -rf "$T"' EXIT
start_daemon "$T/d" --dicom-listen "$DP" --dicom-peers "$T/peers" --series-idle 1 --pacs "tps=dicom://TPS@127.0.0.1:$SCP" || exit 1

# ---- the CT's own grid: an isosurface of a stored series ----
storescu -aet STORESCU -aec SURFD 127.0.0.1 "$DP" "$DD"/*.dcm >"$T/scu" 2>&1
check "the CT series stored on the node by C-STORE" '[ $? = 0 ]'
status GET /series >/dev/null; SUID=$(field series 0 uid)
code=$(status POST "/isosurface?iso=226.5&series=$SUID"); cp "$T/body" "$T/iso.json"
ISO=$(field id); iso_vol=$(field volume_mm3)
check "POST /isosurface?series=UID: 201, the model naming its series and frame of reference" \
    '[ "$code" = 201 ] && [ "$(field referenced_series series_instance_uid)" = "$SUID" ] && [ "$(field frame_of_reference_uid)" = "$(dcmdump +P FrameOfReferenceUID "$DD/IM0001.dcm" | sed "s/.*\[\(.*\)\].*/\1/")" ]'
code=$(status GET "/models/$ISO/mesh?format=seg"); cp "$T/body" "$T/ct.dcm"
check "GET /models/{id}/mesh?format=seg: 200, a DICOM object named ID.dcm, on the stored series' grid (X-Seg-Grid: series)" \
    '[ "$code" = 200 ] && [ "$(header Content-Type)" = application/dicom ] && header Content-Disposition | grep -q "$ISO.dcm" && [ "$(header X-Seg-Grid)" = series ]'
$PY - "$T/ct.dcm" "$DD" 226.5 >"$T/ct.txt" <<'PYEOF'
# the SEG against the CT: geometry frame by frame (each frame to the slice it derives from), the
# references, and the voxels against the CT's samples above iso
import sys, glob, numpy as np, pydicom
seg, iso = pydicom.dcmread(sys.argv[1]), float(sys.argv[3])
ct = {d.SOPInstanceUID: d for d in (pydicom.dcmread(f) for f in glob.glob(sys.argv[2] + "/*.dcm"))}
ct0 = next(iter(ct.values()))
sh = seg.SharedFunctionalGroupsSequence[0]
geo = (int(seg.Rows) == int(ct0.Rows) and int(seg.Columns) == int(ct0.Columns)
       and np.allclose([float(v) for v in sh.PixelMeasuresSequence[0].PixelSpacing], [float(v) for v in ct0.PixelSpacing], atol=1e-6)
       and np.allclose([float(v) for v in sh.PlaneOrientationSequence[0].ImageOrientationPatient], [float(v) for v in ct0.ImageOrientationPatient], atol=1e-6))
bits = np.unpackbits(np.frombuffer(seg.PixelData, np.uint8), bitorder="little")
n_px = int(seg.Rows) * int(seg.Columns)
frames = bits[: int(seg.NumberOfFrames) * n_px].reshape(int(seg.NumberOfFrames), int(seg.Rows), int(seg.Columns))
wrong = inside = 0
seen = set()
for f, item in zip(frames, seg.PerFrameFunctionalGroupsSequence):
    uid = item.DerivationImageSequence[0].SourceImageSequence[0].ReferencedSOPInstanceUID
    d = ct[uid]
    seen.add(uid)
    geo = geo and np.allclose([float(v) for v in item.PlanePositionSequence[0].ImagePositionPatient],
                              [float(v) for v in d.ImagePositionPatient], atol=1e-4)
    hu = d.pixel_array * float(d.RescaleSlope) + float(d.RescaleIntercept)
    wrong += int(np.count_nonzero(f.astype(bool) != (hu > iso)))
    inside += int(f.sum())
# slices without a frame hold no sample above iso
missing = sum(int(np.count_nonzero(d.pixel_array * float(d.RescaleSlope) + float(d.RescaleIntercept) > iso)) for u, d in ct.items() if u not in seen)
refs = seg.ReferencedSeriesSequence[0]
print("geometry", geo, "frames", len(seen), "study", seg.StudyInstanceUID == ct0.StudyInstanceUID,
      "frame", seg.FrameOfReferenceUID == ct0.FrameOfReferenceUID, "series", refs.SeriesInstanceUID == ct0.SeriesInstanceUID
      and {i.ReferencedSOPInstanceUID for i in refs.ReferencedInstanceSequence} == seen,
      "binary", seg.SegmentationType == "BINARY" and int(seg.BitsAllocated) == 1 and len(seg.SegmentSequence) == 1,
      "patient", "PatientName" in seg and "PatientID" in seg and str(seg.PatientName) == "" and seg.PatientID == "")
print("voxels", inside, "wrong", wrong, "missing", missing)
PYEOF
echo "  $(tail -1 "$T/ct.txt")"
check "... each frame at its CT slice's position, the CT's orientation and spacing, its study, frame of reference and series (every image a frame derives from referenced), BINARY, one segment, the patient's name and ID empty" \
    '[ "$(head -1 "$T/ct.txt")" = "geometry True frames 27 study True frame True series True binary True patient True" ]'
grep -q "patient True$" "$T/ct.txt" || head -1 "$T/ct.txt"
wrong=$(sed -n 's/.* wrong \([0-9]*\).*/\1/p' "$T/ct.txt"); missing=$(sed -n 's/.* missing \([0-9]*\)$/\1/p' "$T/ct.txt")
voxels=$(sed -n 's/^voxels \([0-9]*\).*/\1/p' "$T/ct.txt")
# the isosurface on the CT's own grid passes between each sample above iso and its neighbours below:
# a voxel is the model's exactly when its sample is above (a surface through a sample itself would
# be a tie; none here)
check "... its voxels exactly the CT's samples above 226.5 HU ($voxels voxels, $wrong differ)" '[ "${voxels:-0}" -gt 1000 ] && [ "$wrong" = 0 ] && [ "$missing" = 0 ]'
check "... dciodvfy: no errors" 'vfy "$T/ct.dcm"'
grep "^Error" "$T/vfy" | head -5
code=$(status POST "/isosurface?segment=1&iso=0.5" -H "$DCM" --data-binary @"$T/ct.dcm"); back=$(field volume_mm3)
voxel_vol=$(python3 -c "print($voxels * 3.828125 * 3.828125 * 6.0)")
# the same mask made here from the CT (its samples above 226.5 HU, z along the slices' positions),
# posted as raw samples on the CT's grid: surfd's surface of it at 0.5 is the one the SEG must give
$PY - "$DD" 226.5 "$T/mask.raw" <<'PYEOF'
import sys, glob, numpy as np, pydicom
ds = sorted((pydicom.dcmread(f) for f in glob.glob(sys.argv[1] + "/*.dcm")), key=lambda d: float(d.ImagePositionPatient[2]))
m = np.stack([(d.pixel_array * float(d.RescaleSlope) + float(d.RescaleIntercept)) > float(sys.argv[2]) for d in ds])
m.astype(np.uint8).tofile(sys.argv[3])
PYEOF
code2=$(status POST "/isosurface?iso=0.5&dims=64,64,27&type=uint8&spacing=3.828125,3.828125,6&origin=0,0,0" \
        -H 'Content-Type: application/octet-stream' --data-binary @"$T/mask.raw"); mask_vol=$(field volume_mm3)
echo "  isosurface $iso_vol mm3; SEG voxels x voxel volume $voxel_vol mm3; SEG read back at 0.5: $back mm3; the CT's mask at 0.5: $mask_vol mm3"
# a binary mask's surface at 0.5 runs halfway between inside and outside samples, the CT's at 226.5
# HU where its values cross: on 3.8 x 3.8 x 6 mm voxels of a thin skull they differ by some 17 %,
# so the model's volume is no test of the read-back; the same mask's surface is, to rounding
check "POST the SEG back to /isosurface?segment=1&iso=0.5 (surfd's SEG reader): 201, the volume of the CT's own mask's surface (within 1e-6)" \
    '[ "$code" = 201 ] && [ "$code2" = 201 ] && near "$back" "$mask_vol" 1e-6'

# ---- models of a structure set whose CT is not stored: ?spacing ----
: >"$T/models"
for roi in Heart "Lt Lung" "Tumor Bed"; do
    code=$(status POST "/model?roi=$(echo "$roi" | sed 's/ /%20/g')&caps=slab" -H "$DCM" --data-binary @"$RS")
    [ "$code" = 201 ] || bad "POST /model?roi=$roi: $code"
    printf '%s\t%s\t%s\n' "$(field id)" "$roi" "$(field volume_mm3)" >>"$T/models"
done
ids=$(cut -f1 "$T/models" | paste -sd, -); heart=$(head -1 "$T/models" | cut -f1)
rs_series=$(dcmdump +P SeriesInstanceUID "$RS" | sed -n 2p | sed 's/.*\[\(.*\)\].*/\1/')
code=$(status GET "/rtstruct?models=$ids&format=seg")
check "GET /rtstruct?models=...&format=seg, their CT not stored: 422 at ?models naming the series, saying how (C-STORE, pull, ?spacing)" \
    '[ "$code" = 422 ] && is_problem 422 && pointer "?models" && grep -q "$rs_series" "$T/body" && grep -q "spacing" "$T/body" && grep -q "pull" "$T/body"'
code=$(status GET "/models/$heart/mesh?format=seg")
check "... GET /models/{id}/mesh?format=seg of one of them: 422 at ?format" '[ "$code" = 422 ] && pointer "?format"'
code=$(status GET "/rtstruct?models=$ids&format=seg&spacing=2"); cp "$T/body" "$T/rs.dcm"
check "... with ?spacing=2: 200, a DICOM object named after its job (X-Seg-Grid: spacing)" \
    '[ "$code" = 200 ] && header Content-Disposition | grep -q "$(header X-Job-Id).dcm" && [ "$(header X-Seg-Grid)" = spacing ]'
$PY - "$RS" "$T/rs.dcm" "$T/models" >"$T/rs.txt" <<'PYEOF'
# segments against the source's ROIs (label, colour back from CIELab), each segment's voxels x 8 mm3
# against its model's volume; the references the structure set's
import sys, numpy as np, pydicom
src, seg = pydicom.dcmread(sys.argv[1]), pydicom.dcmread(sys.argv[2])
names = {int(r.ROINumber): r.ROIName for r in src.StructureSetROISequence}
colour = {names[int(r.ReferencedROINumber)]: [int(v) for v in r.ROIDisplayColor] for r in src.ROIContourSequence}
def srgb(lab16):
    L, a, b = lab16[0] / 65535 * 100, lab16[1] / 65535 * 255 - 128, lab16[2] / 65535 * 255 - 128
    fy = (L + 16) / 116; fx, fz = fy + a / 500, fy - b / 200
    finv = lambda t: t ** 3 if t > 6 / 29 else 3 * (6 / 29) ** 2 * (t - 4 / 29)
    X, Y, Z = 0.95047 * finv(fx), finv(fy), 1.08883 * finv(fz)
    lin = [3.2404542 * X - 1.5371385 * Y - 0.4985314 * Z, -0.9692660 * X + 1.8760108 * Y + 0.0415560 * Z,
           0.0556434 * X - 0.2040259 * Y + 1.0572252 * Z]
    return [round(255 * (12.92 * c if c <= 0.0031308 else 1.055 * max(c, 0) ** (1 / 2.4) - 0.055)) for c in lin]
bits = np.unpackbits(np.frombuffer(seg.PixelData, np.uint8), bitorder="little")
n_px = int(seg.Rows) * int(seg.Columns)
count = {}
for k, item in enumerate(seg.PerFrameFunctionalGroupsSequence):
    s = int(item.SegmentIdentificationSequence[0].ReferencedSegmentNumber)
    count[s] = count.get(s, 0) + int(bits[k * n_px:(k + 1) * n_px].sum())
sp = [float(v) for v in seg.SharedFunctionalGroupsSequence[0].PixelMeasuresSequence[0].PixelSpacing]
dz = float(seg.SharedFunctionalGroupsSequence[0].PixelMeasuresSequence[0].SliceThickness)
models = [l.rstrip("\n").split("\t") for l in open(sys.argv[3])]
ok = len(seg.SegmentSequence) == 3
for s, (mid, name, vol) in zip(seg.SegmentSequence, models):
    back = srgb([int(v) for v in s.RecommendedDisplayCIELabValue])
    ok = ok and s.SegmentLabel == name and s.SegmentAlgorithmType == "AUTOMATIC" and max(abs(x - y) for x, y in zip(back, colour[name])) <= 1
    print("%s\t%s\t%.1f\t%s" % (name, vol, count.get(int(s.SegmentNumber), 0) * sp[0] * sp[1] * dz, back), file=sys.stderr)
frame = src.ReferencedFrameOfReferenceSequence[0].FrameOfReferenceUID
print("segments", ok, "spacing", sp == [2.0, 2.0] and dz == 2.0, "study", seg.StudyInstanceUID == src.StudyInstanceUID,
      "frame", seg.FrameOfReferenceUID == frame, "no series", "ReferencedSeriesSequence" not in seg,
      "patient", str(seg.PatientName) == "" and seg.PatientID == "")
PYEOF
$PY - "$RS" "$T/rs.dcm" "$T/models" 2>"$T/vols.txt" >/dev/null
check "... 3 segments in the list's order, labelled by their models, AUTOMATIC, each colour the source ROI's (CIELab back to sRGB within 1), 2 mm voxels, the structure set's study and frame of reference, no series referenced, the patient's name and ID empty" \
    '[ "$(cat "$T/rs.txt")" = "segments True spacing True study True frame True no series True patient True" ]'
grep -q "True$" "$T/rs.txt" || cat "$T/rs.txt"
# a voxel is the model's when its centre is inside: the count is the volume's estimate, off by the
# partial voxels round the surface (2 mm voxels: within 2 % for a heart, 5 % for a smaller bed)
while IFS="$(printf '\t')" read -r name vol voxvol rgb; do
    echo "  $name: model $vol mm3, SEG voxels $voxvol mm3 (colour $rgb)"
    tol=0.02; [ "$name" = "Tumor Bed" ] && tol=0.05
    check "... $name: its voxels' volume within $(python3 -c "print(int($tol * 100))") % of the model's" 'near "$voxvol" "$vol" $tol'
done <"$T/vols.txt"
check "... dciodvfy: no errors" 'vfy "$T/rs.dcm"'
grep "^Error" "$T/vfy" | head -5
code=$(status POST "/isosurface?segment=1&iso=0.5" -H "$DCM" --data-binary @"$T/rs.dcm"); back=$(field volume_mm3)
heart_vol=$(head -1 "$T/models" | cut -f3)
echo "  Heart read back at 0.5: $back mm3 (model $heart_vol)"
check "... segment 1 (Heart) read back by /isosurface?segment=1&iso=0.5 within 3 % of its model's volume" '[ "$code" = 201 ] && near "$back" "$heart_vol" 0.03'
code=$(status GET "/models/$heart/mesh?format=seg&spacing=3")
check "GET /models/{id}/mesh?format=seg&spacing=3: one segment, the Heart" '[ "$code" = 200 ] && [ "$($PY -c "import pydicom,sys; d = pydicom.dcmread(sys.argv[1]); print(len(d.SegmentSequence), d.SegmentSequence[0].SegmentLabel)" "$T/body")" = "1 Heart" ]'

# ---- sent by C-STORE: DCMTK's storescp receives it ----
code=$(status POST "/models/$ISO/send?pacs=tps&as=seg")
check "POST /models/{id}/send?pacs=tps&as=seg: 200, stored by the peer" '[ "$code" = 200 ] && [ "$(field as)" = seg ] && [ "$(field instances 0 stored)" = True ]'
got=$(ls "$T/scp" | head -1)
check "... storescp holds a Segmentation of the CT's series" '[ -n "$got" ] && [ "$($PY -c "import pydicom,sys; d = pydicom.dcmread(sys.argv[1]); print(d.Modality, d.ReferencedSeriesSequence[0].SeriesInstanceUID)" "$T/scp/$got")" = "SEG $SUID" ]'

# ---- bad requests: 4xx at their pointer, the caps before any work ----
check "?format=nope on /rtstruct: 422 at ?format" '[ "$(status GET "/rtstruct?models=$ids&format=nope")" = 422 ] && pointer "?format"'
check "?format=seg&spacing=0: 422 at ?spacing" '[ "$(status GET "/rtstruct?models=$ids&format=seg&spacing=0")" = 422 ] && pointer "?spacing"'
check "?spacing=abc on /models/{id}/mesh?format=seg: 422 at ?spacing" '[ "$(status GET "/models/$heart/mesh?format=seg&spacing=abc")" = 422 ] && pointer "?spacing"'
jobs() { curl -s "$URL/jobs" | python3 -c "import json,sys; print(len(json.load(sys.stdin)['jobs']))"; }
before=$(jobs)
t0=$(date +%s%N)
code=$(status GET "/rtstruct?models=$ids&format=seg&spacing=0.05")
ms=$(( ($(date +%s%N) - t0) / 1000000 ))
check "0.05 mm voxels over three ROIs (over 2^31 bits): 422 at ?spacing naming the cap, in ${ms} ms, before any voxel" \
    '[ "$code" = 422 ] && pointer "?spacing" && grep -q 2147483648 "$T/body" && [ "$ms" -lt 2000 ]'
check "... no job was made of it" '[ "$(jobs)" = "$before" ] && [ "$before" -gt 0 ]'
check "an isosurface and a structure set's model (two frames of reference) in one SEG: 422 at ?models" \
    '[ "$(status GET "/rtstruct?models=$ISO,$heart&format=seg")" = 422 ] && pointer "?models" && grep -q "frames of reference" "$T/body"'
check "as=bogus on send: 422 at ?as listing seg" '[ "$(status POST "/models/$ISO/send?pacs=tps&as=bogus")" = 422 ] && pointer "?as" && grep -q seg "$T/body"'
check "as=seg of a model whose CT is not stored, no ?spacing: 422 at ?format" '[ "$(status POST "/models/$heart/send?pacs=tps&as=seg")" = 422 ] && pointer "?format"'
check "?format=seg on a mesh of a model not stored: 404" '[ "$(status GET "/models/0123456789abcdef0123456789abcdef/mesh?format=seg")" = 404 ]'

# the clients: the same SEG of the isosurface as curl's
SURFD_URL="$URL" build/surfctl rtstruct "$ISO" -o "$T/cli.dcm" --format seg >/dev/null 2>"$T/err"; rc=$?
check "surfctl rtstruct ID --format seg -o OUT.dcm: a Segmentation of the same frames as GET /models/{id}/mesh?format=seg" '[ $rc = 0 ] && $PY -c "
import pydicom, sys
a, b = pydicom.dcmread(sys.argv[1]), pydicom.dcmread(sys.argv[2])
sys.exit(0 if a.Modality == b.Modality == \"SEG\" and a.NumberOfFrames == b.NumberOfFrames and a.PixelData == b.PixelData else 1)" "$T/cli.dcm" "$T/ct.dcm"'
check "the Python client's rtstruct(ID, format=\"seg\"): the same frames" 'PYTHONPATH=client/python python3 -c "
import sys, surfd
c = surfd.Client(sys.argv[1])
open(sys.argv[3], \"wb\").write(c.rtstruct(sys.argv[2], format=\"seg\"))" "$URL" "$ISO" "$T/py.dcm" && $PY -c "
import pydicom, sys
a, b = pydicom.dcmread(sys.argv[1]), pydicom.dcmread(sys.argv[2])
sys.exit(0 if a.PixelData == b.PixelData and a.NumberOfFrames == b.NumberOfFrames else 1)" "$T/py.dcm" "$T/ct.dcm"'
finish
