#!/bin/sh
# Models back to the planning system (issue 18): GET /models/{id}/mesh?format=dicom-stl is a DICOM
# Encapsulated STL of the mesh; GET /models/{id}/rtstruct is a DICOM RT Structure
# Set of the model's sections (its own slices, or ?spacing=MM apart; an isosurface's grid slices)
# that dciodvfy (dicom3tools) passes without errors, that our own reader takes back with the
# model's volume, that references the source's study and frame of reference and carries no patient
# data; bad spacings are 422s at ?spacing.
. "$(dirname "$0")/lib.inc"
C="${SURFD_DATA:-../shared/data}/contours"
RS="$C/dicompyler-core_example_rtss.dcm"
[ -f "$RS" ] || { bad "../shared/data/contours not found"; finish; }
DCM='Content-Type: application/dicom'
field() { python3 -c "import json,sys; print(json.load(open(sys.argv[1])).get(sys.argv[2]))" "$T/body" "$1"; }
near() { python3 -c "import sys; sys.exit(0 if abs(float(sys.argv[1]) / float(sys.argv[2]) - 1) < float(sys.argv[3]) else 1)" "$@"; }
start_daemon "$T/d" || exit 1
code=$(status POST "/model?roi=Heart" -H "$DCM" --data-binary @"$RS"); id=$(field id); vol=$(field volume_mm3)
frame=$(field frame_of_reference_uid); study=$(field study_instance_uid); n=$(field contours)
check "a model from an RT Structure Set keeps its study and frame of reference (for exports)" '[ "$code" = 201 ] && [ -n "$frame" ] && [ "$frame" != None ] && [ -n "$study" ]'
code=$(status GET "/models/$id/rtstruct"); cp "$T/body" "$T/heart.dcm"
check "GET /models/{id}/rtstruct: a DICOM object, named ID.dcm" '[ "$code" = 200 ] && [ "$(header Content-Type)" = application/dicom ] && header Content-Disposition | grep -q "$id.dcm" && [ "$(dd if="$T/heart.dcm" bs=1 skip=128 count=4 2>/dev/null)" = DICM ]'
if command -v dciodvfy >/dev/null; then
    dciodvfy "$T/heart.dcm" >"$T/vfy" 2>&1
    check "... dciodvfy: no errors" '! grep -q "^Error" "$T/vfy"'
    grep "^Error" "$T/vfy" | head -5
    dcdump "$T/heart.dcm" >"$T/dump" 2>&1
    check "... the patient's name and ID present and empty; the source's study and frame of reference referenced" 'grep "(0x0010,0x0010)" "$T/dump" | grep -q "<>" && grep "(0x0010,0x0020)" "$T/dump" | grep -q "<>" && grep -q "<$study>" "$T/dump" && grep -q "<$frame>" "$T/dump"'
else
    bad "no dciodvfy (deploy/install-deps.sh installs dicom3tools)"
fi
code=$(status POST "/volume?roi=Heart" -H "$DCM" --data-binary @"$T/heart.dcm")
check "... read back by our own reader: the model's volume within 0.1 %, its slices" '[ "$code" = 200 ] && near "$(field volume_mm3)" "$vol" 0.001 && [ "$(field contours)" -ge "$n" ]'
code=$(status GET "/models/$id/rtstruct?spacing=1.5"); cp "$T/body" "$T/fine.dcm"
code=$(status POST "/volume?roi=Heart" -H "$DCM" --data-binary @"$T/fine.dcm")
check "?spacing=1.5: more sections (the ends kept), the volume within 0.1 %" '[ "$code" = 200 ] && [ "$(field slices)" -gt "$n" ] && near "$(field volume_mm3)" "$vol" 0.001'
check "?spacing=0.001: more sections than a structure set holds, 422 at ?spacing (the cap)" '[ "$(status GET "/models/$id/rtstruct?spacing=0.001")" = 422 ] && grep -q "?spacing" "$T/body" && grep -q "sections" "$T/body"'
for bad_spacing in 0 -1 5000 x; do
    check "?spacing=$bad_spacing: 422 at ?spacing" '[ "$(status GET "/models/$id/rtstruct?spacing=$bad_spacing")" = 422 ] && grep -q "?spacing" "$T/body"'
done
code=$(status POST /model -H 'Content-Type: application/json' --data-binary @"$C/synthetic_ellipsoid.json"); eid=$(field id); evol=$(field volume_mm3)
code=$(status GET "/models/$eid/rtstruct"); cp "$T/body" "$T/ell.dcm"
code=$(status POST /volume -H "$DCM" --data-binary @"$T/ell.dcm")
check "a contour JSON model: fresh UIDs, read back within 0.1 %" '[ "$code" = 200 ] && near "$(python3 -c "import json,sys; print(json.load(open(sys.argv[1]))[\"models\"][0][\"volume_mm3\"])" "$T/body")" "$evol" 0.001'
code=$(status POST "/isosurface?iso=226.5&dims=64,64,64&type=int16&spacing=0.9570312,0.9570312,1.5" -H 'Content-Type: application/octet-stream' --data-binary @"${SURFD_DATA:-../shared/data}/volumes/ct_head_crop64_int16.raw")
iid=$(field id); ivol=$(field volume_mm3)
code=$(status GET "/models/$iid/rtstruct"); cp "$T/body" "$T/ct.dcm"
code=$(status POST /volume -H "$DCM" --data-binary @"$T/ct.dcm")
check "an isosurface model: cut at its grid's slices, read back within 2 % (flat ends at the last slices)" '[ "$code" = 200 ] && near "$(python3 -c "import json,sys; print(json.load(open(sys.argv[1]))[\"models\"][0][\"volume_mm3\"])" "$T/body")" "$ivol" 0.02'
code=$(status GET "/models/$id/mesh?format=dicom-stl"); cp "$T/body" "$T/heart_stl.dcm"
check "?format=dicom-stl: a DICOM Encapsulated STL, named ID.dcm" '[ "$code" = 200 ] && [ "$(header Content-Type)" = application/dicom ] && header Content-Disposition | grep -q "$id.dcm"'
if command -v dciodvfy >/dev/null; then
    dciodvfy "$T/heart_stl.dcm" >"$T/vfy" 2>&1
    check "... dciodvfy knows it (EncapsulatedSTL) and finds no errors" 'grep -q EncapsulatedSTL "$T/vfy" && ! grep -q "^Error" "$T/vfy"'
fi
code=$(status GET "/models/$id/mesh?format=stl"); cp "$T/body" "$T/heart.stl"
check "... holding the very STL of ?format=stl, referencing the source's study and frame of reference" 'python3 -c "
import struct, sys
d = open(sys.argv[1], \"rb\").read(); i = d.find(b\"\\x42\\x00\\x11\\x00OB\")
n = struct.unpack_from(\"<I\", d, i + 8)[0]; stl = open(sys.argv[2], \"rb\").read()
sys.exit(0 if i > 0 and d[i + 12:i + 12 + len(stl)] == stl and sys.argv[3].encode() in d and sys.argv[4].encode() in d else 1)" "$T/heart_stl.dcm" "$T/heart.stl" "$study" "$frame"'
check "no such model: 404" '[ "$(status GET /models/0123456789abcdef0123456789abcdef/rtstruct)" = 404 ]'
finish
