#!/bin/sh
# A whole RT Structure Set back (issue 44): GET /rtstruct?models=ID,ID,... is one structure set with
# every listed model an ROI, numbered 1..n in the list's order and named by the model, coloured and
# typed as its source structure set said (else a palette by ROI number, and a type by name), in the
# source's study and frame of reference, referencing its series' images, with the patient's name
# and ID present and empty; dciodvfy finds no errors; holes are cut into their outer contours, so
# plastimatch, which fills every contour, reads each ROI's volume (a tube holding a rod too) within
# 1 % of the model's, as it does even-odd; our own reader takes it back with the volumes; bad
# lists are 4xx problems pointing at ?models. GET /models/{id}/rtstruct stays the one-model case.
. "$(dirname "$0")/lib.inc"
PY=/usr/bin/python3 # Debian's: pydicom, numpy
$PY -c "import pydicom, numpy" 2>/dev/null || { bad "python3-pydicom or python3-numpy is missing (deploy/install-deps.sh installs them)"; checks_done; exit 1; }
command -v plastimatch >/dev/null && command -v dciodvfy >/dev/null ||
    { bad "plastimatch or dciodvfy (dicom3tools) is missing (deploy/install-deps.sh installs them)"; checks_done; exit 1; }
C="${SURFD_DATA:-../shared/data}/contours"
RS="$C/dicompyler-core_example_rtss.dcm"
[ -f "$RS" ] || { bad "../shared/data/contours not found"; finish; }
DCM='Content-Type: application/dicom'
field() { python3 -c "import json,sys; print(json.load(open(sys.argv[1])).get(sys.argv[2]))" "$T/body" "$1"; }
near() { python3 -c "import sys; sys.exit(0 if abs(float(sys.argv[1]) / float(sys.argv[2]) - 1) < float(sys.argv[3]) else 1)" "$@"; }
pointer() { grep -q "\"pointer\":\"?models\"" "$T/body"; }
start_daemon "$T/d" || exit 1

# the models: three ROIs of the dicompyler structure set (slab caps: as planning systems and
# plastimatch count the ends), and a tube holding a rod, in contour JSON on the same planes
: >"$T/models"
for roi in Heart "Lt Lung" "Tumor Bed"; do
    code=$(status POST "/model?roi=$(echo "$roi" | sed 's/ /%20/g')&caps=slab" -H "$DCM" --data-binary @"$RS")
    [ "$code" = 201 ] || bad "POST /model?roi=$roi: $code"
    printf '%s\t%s\t%s\n' "$(field id)" "$roi" "$(field volume_mm3)" >>"$T/models"
done
python3 -c "
import json, math
def circle(r, n, cw):
    pts = [[r * math.cos(2 * math.pi * k / n), -150 + r * math.sin(2 * math.pi * k / n)] for k in range(n)]
    return {'points': pts[::-1] if cw else pts}
# planes of the structure set above (-98.44 + 3 k): the tube's wall and the rod in its bore
print(json.dumps({'name': 'PTV shell', 'caps': 'slab', 'slices': [
    {'z': -98.44 + 3 * k, 'contours': [circle(30, 96, False), circle(20, 72, True), circle(10, 48, False)]} for k in range(10)]}))" >"$T/shell.json"
code=$(status POST /model -H 'Content-Type: application/json' --data-binary @"$T/shell.json")
check "a tube holding a rod (three contours a slice, a hole between): 201" '[ "$code" = 201 ]'
printf '%s\t%s\t%s\n' "$(field id)" "PTV shell" "$(field volume_mm3)" >>"$T/models"
shell_vol=$(field volume_mm3)
check "... its volume even-odd: the wall and the rod, not the whole cylinder" 'near "$shell_vol" "$(python3 -c "import math; print(math.pi * (900 - 400 + 100) * 30)")" 0.01'
ids=$(cut -f1 "$T/models" | paste -sd, -)

code=$(status GET "/rtstruct?models=$ids"); cp "$T/body" "$T/set.dcm"
check "GET /rtstruct?models= (4 models): 200, a DICOM object, named after its job" '[ "$code" = 200 ] && [ "$(header Content-Type)" = application/dicom ] && header Content-Disposition | grep -q "$(header X-Job-Id).dcm" && [ "$(dd if="$T/set.dcm" bs=1 skip=128 count=4 2>/dev/null)" = DICM ]'
# what the source says of its ROIs, and what the export says, as NAME|COLOUR|TYPE lines
$PY - "$RS" >"$T/source.txt" <<'PYEOF'
import sys, pydicom
ds = pydicom.dcmread(sys.argv[1])
names = {int(r.ROINumber): r.ROIName for r in ds.StructureSetROISequence}
types = {int(o.ReferencedROINumber): o.RTROIInterpretedType for o in ds.RTROIObservationsSequence}
for r in ds.ROIContourSequence:
    n = int(r.ReferencedROINumber)
    print("%s|%s|%s" % (names[n], "\\".join(str(int(v)) for v in r.ROIDisplayColor), types.get(n, "")))
PYEOF
$PY - "$T/set.dcm" >"$T/export.txt" <<'PYEOF'
import sys, pydicom
ds = pydicom.dcmread(sys.argv[1])
obs = {int(o.ReferencedROINumber): o.RTROIInterpretedType for o in ds.RTROIObservationsSequence}
col = {int(r.ReferencedROINumber): "\\".join(str(int(v)) for v in r.ROIDisplayColor) for r in ds.ROIContourSequence}
for r in ds.StructureSetROISequence:
    n = int(r.ROINumber)
    print("%d|%s|%s|%s|%s|%s" % (n, r.ROIName, col[n], obs[n], r.ROIGenerationAlgorithm, r.ROIGenerationDescription))
PYEOF
check "... 4 ROIs numbered 1..4 in the list's order, named by their models, generated AUTOMATIC by surfd" '[ "$(cut -d"|" -f1,2,5,6 "$T/export.txt" | tr "\n" ";")" = "1|Heart|AUTOMATIC|surfd;2|Lt Lung|AUTOMATIC|surfd;3|Tumor Bed|AUTOMATIC|surfd;4|PTV shell|AUTOMATIC|surfd;" ]'
check "... the source's colour and interpreted type for each ROI from it" 'for roi in Heart "Lt Lung" "Tumor Bed"; do [ "$(grep "^$roi|" "$T/source.txt")" = "$(grep "|$roi|" "$T/export.txt" | cut -d"|" -f2-4)" ] || exit 1; done'
check "... the tube: the palette's fourth colour, PTV by its name" '[ "$(grep "|PTV shell|" "$T/export.txt" | cut -d"|" -f3,4)" = "214\\39\\40|PTV" ]'
$PY - "$RS" "$T/set.dcm" >"$T/refs.txt" <<'PYEOF'
import sys, pydicom
src, out = pydicom.dcmread(sys.argv[1]), pydicom.dcmread(sys.argv[2])
ser = lambda d: d.ReferencedFrameOfReferenceSequence[0].RTReferencedStudySequence[0].RTReferencedSeriesSequence[0]
s, o = ser(src), ser(out)
images = {i.ReferencedSOPInstanceUID for i in s.ContourImageSequence}
per_contour = [c.ContourImageSequence[0].ReferencedSOPInstanceUID for r in out.ROIContourSequence[:3] for c in r.ContourSequence]
frame = src.ReferencedFrameOfReferenceSequence[0].FrameOfReferenceUID
print("study", out.StudyInstanceUID == src.StudyInstanceUID, "frame", out.FrameOfReferenceUID == frame
      and out.ReferencedFrameOfReferenceSequence[0].FrameOfReferenceUID == frame and len(images),
      "series", o.SeriesInstanceUID == s.SeriesInstanceUID, "images", {i.ReferencedSOPInstanceUID for i in o.ContourImageSequence} == images,
      "contours", len(per_contour) > 0 and set(per_contour) <= images,
      "patient", "PatientName" in out and "PatientID" in out and str(out.PatientName) == "" and out.PatientID == "")
PYEOF
check "... the source's study, frame of reference, series and its 98 images; each source ROI's contour the image in its plane; the patient's name and ID empty" '[ "$(cat "$T/refs.txt")" = "study True frame 98 series True images True contours True patient True" ]'
grep -q "True$" "$T/refs.txt" || cat "$T/refs.txt"
dciodvfy "$T/set.dcm" >"$T/vfy" 2>&1
check "... dciodvfy: no errors" 'grep -q "RTStructureSet" "$T/vfy" && ! grep -q "^Error" "$T/vfy"'
grep "^Error" "$T/vfy" | head -5

# plastimatch: every contour filled (its default), and xor'd (even-odd) for comparison
$PY tests/tools/plastimatch_volumes.py "$T/set.dcm" 3 >"$T/pl_or.txt"
$PY tests/tools/plastimatch_volumes.py "$T/set.dcm" 3 --xor >"$T/pl_xor.txt"
while IFS="$(printf '\t')" read -r id name vol; do
    pl=$(grep "^$name	" "$T/pl_or.txt" | cut -f2); px=$(grep "^$name	" "$T/pl_xor.txt" | cut -f2)
    echo "  $name: surfd $vol mm3, plastimatch $pl (filled), $px (xor)"
    check "plastimatch reads $name within 1 % of surfd's model volume, filling every contour" '[ -n "$pl" ] && near "$pl" "$vol" 0.01'
    check "... and as even-odd reads it (holes cut in, not drawn apart: filled = xor'd within 0.05 %)" '[ -n "$px" ] && near "$pl" "$px" 0.0005'
done <"$T/models"

code=$(status POST "/volume?caps=slab" -H "$DCM" --data-binary @"$T/set.dcm"); cp "$T/body" "$T/back.json"
while IFS="$(printf '\t')" read -r id name vol; do
    back=$(python3 -c "import json,sys; print([m['volume_mm3'] for m in json.load(open(sys.argv[1]))['models'] if m['name'] == sys.argv[2]][0])" "$T/back.json" "$name" 2>/dev/null)
    check "round trip through POST /volume: $name within 0.1 % of its model ($back)" '[ "$code" = 200 ] && [ -n "$back" ] && near "$back" "$vol" 0.001'
done <"$T/models"

heart=$(head -1 "$T/models" | cut -f1)
code=$(status GET "/models/$heart/rtstruct"); cp "$T/body" "$T/one.dcm"
check "GET /models/{id}/rtstruct: the one-model case, ROI 1, the source's colour and type, named ID.dcm" '[ "$code" = 200 ] && header Content-Disposition | grep -q "$heart.dcm" && [ "$($PY -c "import pydicom,sys; d = pydicom.dcmread(sys.argv[1]); print(len(d.StructureSetROISequence), d.StructureSetROISequence[0].ROINumber, d.ROIContourSequence[0].ROIDisplayColor, d.RTROIObservationsSequence[0].RTROIInterpretedType)" "$T/one.dcm")" = "1 1 [255, 128, 0] ORGAN" ]'

# bad lists: 4xx problems at ?models
code=$(status POST "/model?roi=Bladder" -H "$DCM" --data-binary @"$C/slicerrt_EclipseProstatePhantom_RS.dcm"); other=$(field id)
check "models of two frames of reference: 422 at ?models naming both" '[ "$(status GET "/rtstruct?models=$heart,$other")" = 422 ] && pointer && grep -q "$heart" "$T/body" && grep -q "$other" "$T/body" && grep -q "frames of reference" "$T/body"'
check "an unknown id: 404 at ?models naming it" '[ "$(status GET "/rtstruct?models=$heart,0123456789abcdef0123456789abcdef")" = 404 ] && is_problem 404 && pointer && grep -q 0123456789abcdef0123456789abcdef "$T/body"'
check "... not an id at all: 404 naming it" '[ "$(status GET "/rtstruct?models=$heart,nosuch")" = 404 ] && pointer && grep -q nosuch "$T/body"'
check "an empty list: 422 at ?models" '[ "$(status GET "/rtstruct?models=")" = 422 ] && is_problem 422 && pointer'
check "no list: 422 at ?models" '[ "$(status GET /rtstruct)" = 422 ] && pointer'
check "an empty entry: 422 at ?models" '[ "$(status GET "/rtstruct?models=$heart,,$heart")" = 422 ] && pointer'
check "a model listed twice: 422 at ?models naming it" '[ "$(status GET "/rtstruct?models=$heart,$heart")" = 422 ] && pointer && grep -q "listed twice" "$T/body"'
many=$(python3 -c "print(','.join('%032x' % k for k in range(257)))")
check "257 models (the cap is 256): 422 at ?models, before any is looked up" '[ "$(status GET "/rtstruct?models=$many")" = 422 ] && pointer && grep -q "at most 256" "$T/body"'
many=$(python3 -c "print(','.join('%032x' % k for k in range(256)))")
check "... 256 unknown ones: 404 (the cap is not the refusal)" '[ "$(status GET "/rtstruct?models=$many")" = 404 ]'
check "?spacing=0 on a set: 422 at ?spacing" '[ "$(status GET "/rtstruct?models=$heart&spacing=0")" = 422 ] && grep -q "?spacing" "$T/body"'
check "no patient name or ID in the log" '! grep -qi "boost" "$T/daemon.log"'
finish
