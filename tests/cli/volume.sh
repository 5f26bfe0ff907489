#!/bin/sh
# `surfd volume` as a user runs it: JSON figures for real and synthetic contours, clear failures.
. "$(dirname "$0")/lib.inc"

for f in synthetic_ellipsoid synthetic_bean synthetic_torus_branching dicompyler_heart dicompyler_tumor_bed \
         dicompyler_lt_lung_multicontour eclipse_bladder eclipse_ptv eclipse_rectum eclipse_femoral_head_lt eclipse_body; do
    $S volume "$C/$f.json" >"$T/out" 2>"$T/err"
    check "volume $f" '[ $? -eq 0 ] && grep -q "\"volume_mm3\":[1-9]" "$T/out" && grep -q "\"trapezoid\":" "$T/out" && grep -q "\"caps\":\"flat\"" "$T/out"'
done
printf '{"slices":[{"z":0,"contours":[{"points":[[0,0],[2,0],[0,2]]},{"points":[[1,-1],[1,3],[-1,1]]}]},{"z":1,"points":[[0,0],[1,0],[0,1]]}]}' >"$T/o.json"
$S volume "$T/o.json" >/dev/null 2>"$T/err"; rc=$?
check "overlapping contours on one slice" '[ $rc -eq 1 ] && grep -q "/slices/0/contours/1/points" "$T/err"'
# a hole that is its body's own contour, on the first level (tests/api/mutate.sh found it answered as out of memory)
printf '{"slices":[{"z":1,"points":[[0,0],[10,0],[10,10],[0,10]]},{"z":1,"points":[[0,0],[10,0],[10,10],[0,10]]},{"z":2,"points":[[1,1],[9,1],[5,9]]}]}' >"$T/h.json"
$S volume "$T/h.json" >"$T/out" 2>"$T/err"
check "a hole on its body's own contour: figures, not out of memory" '[ $? -eq 0 ] && grep -q "\"chains\":3" "$T/out"'
printf '{"slices":[{"z":0,"points":[[0,0],[1,1],[1,0],[0,1]]},{"z":1,"points":[[0,0],[1,0],[0,1]]}]}' >"$T/x.json"
$S volume "$T/x.json" >/dev/null 2>"$T/err"; rc=$?
check "self-crossing contour" '[ $rc -eq 1 ] && grep -q "crosses itself" "$T/err" && grep -q "at /slices/0/points" "$T/err"'
# DICOM RT Structure Sets
$S volume "$C/dicompyler-core_example_rtss.dcm" >"$T/out" 2>"$T/err"
check "rtstruct: every ROI with contours" '[ $? -eq 0 ] && [ "$(python3 -c "import json, sys; print(len(json.load(open(sys.argv[1]))[\"models\"]))" "$T/out")" -eq 9 ] && grep -q "\"name\":\"Lt Lung\"" "$T/out"'
$S volume "$C/dicompyler-core_example_rtss.dcm" --roi Heart >"$T/out"
check "rtstruct --roi Heart equals the JSON file" '[ $? -eq 0 ] && grep -q "\"volume_mm3\":434477.95" "$T/out" && ! grep -q "\"models\"" "$T/out"'
python3 -c "import sys; open(sys.argv[2], 'wb').write(open(sys.argv[1], 'rb').read()[132:])" "$C/dicompyler-core_example_rtss.dcm" "$T/np.dcm"
$S volume "$T/np.dcm" --roi Heart >"$T/out" 2>"$T/err"
check "an RT Structure Set without its preamble and DICM (PS3.10 allows it): read as DICOM, the same Heart" '[ $? -eq 0 ] && grep -q "\"volume_mm3\":434477.95" "$T/out"'
$S volume "$C/slicerrt_EclipseProstatePhantom_RS.dcm" --roi Bladder --caps slab >"$T/out"
check "rtstruct --caps slab" '[ $? -eq 0 ] && grep -q "\"caps\":\"slab\"" "$T/out" && grep -q "\"volume_mm3\":11775" "$T/out"'
$S volume "$C/dicompyler-core_example_rtss.dcm" --roi Nope >/dev/null 2>"$T/err"; rc=$?
check "rtstruct unknown roi" '[ $rc -eq 1 ] && grep -q "?roi" "$T/err"'
ct=$(ls "${SURFD_DATA:-../shared/data}"/volumes/dicom_pydicom_ct5n_16x16x5/* | head -n 1)
$S volume "$ct" >/dev/null 2>"$T/err"; rc=$?
check "a CT image is not a structure set" '[ $rc -eq 1 ] && grep -q "not an RT Structure Set" "$T/err"'
# `surfd model`: the figures, and the mesh and patches the service would serve
$S model "$C/synthetic_bean.json" --caps dome --mesh "$T/b.stl" --patches "$T/b.json" >"$T/out" 2>"$T/err"
check "model --caps dome overrides the file's caps" '[ $? -eq 0 ] && grep -q "\"caps\":\"dome\"" "$T/out"'
vol=$(sed 's/.*"volume_mm3":\([0-9.]*\).*/\1/' "$T/out")
check "model --mesh: a closed STL holding the volume" 'python3 tests/tools/stl_check.py "$T/b.stl" "$vol" >"$T/err"'
$S render "$T/b.json" -o "$T/b.png" --width 64 --height 48 2>"$T/err"
check "model --patches: a scene surfd renders" '[ $? -eq 0 ] && [ -s "$T/b.png" ]'
for f in ply obj; do
    $S model "$C/dicompyler-core_example_rtss.dcm" --roi Heart --mesh "$T/h.$f" --tolerance 0.5 >/dev/null 2>"$T/err"
    check "model --mesh $f" '[ $? -eq 0 ] && { head -c 3 "$T/h.$f" | grep -q ply || grep -q "^f 1 " "$T/h.$f" || grep -q "^f " "$T/h.$f"; }'
done
$S model "$C/dicompyler-core_example_rtss.dcm" --mesh "$T/h.stl" >/dev/null 2>"$T/err"; rc=$?
check "model --mesh of several ROIs asks for one" '[ $rc -eq 1 ] && grep -q "choose one with --roi" "$T/err"'
$S model "$C/synthetic_bean.json" --mesh "$T/b.vrml" >/dev/null 2>"$T/err"; rc=$?
check "model --mesh of an unknown format" '[ $rc -eq 1 ] && grep -q "stl, ply, obj, vtp, vtk, dicom-stl, seg or delta" "$T/err"'
for m in linear-parabolic coons bspline; do
    $S volume "$C/dicompyler-core_example_rtss.dcm" --roi Heart --method $m >"$T/out" 2>"$T/err"
    check "volume --method $m" '[ $? -eq 0 ] && grep -q "\"method\":\"$m\"" "$T/out" && grep -q "\"volume_mm3\":4[0-9][0-9][0-9][0-9][0-9]" "$T/out"'
done
$S volume "$C/synthetic_ellipsoid.json" --parameterisation polar >"$T/out" 2>"$T/err"
check "volume --parameterisation polar" '[ $? -eq 0 ] && grep -q "\"parameterisation\":\"polar\"" "$T/out" && grep -q "\"volume_mm3\":1238" "$T/out"'
$S volume "$C/synthetic_bean.json" --method nurbs >/dev/null 2>"$T/err"; rc=$?
check "volume --method unknown" '[ $rc -eq 1 ] && grep -q "at ?method" "$T/err"'
$S volume "$T/none.json" 2>/dev/null; rc=$?
check "missing file" '[ $rc -eq 1 ]'
$S volume "$C/dicompyler-core_example_rtss.dcm" >"$T/out" 2>/dev/null
check "an RT Structure Set's ROI without contours is listed as skipped, with the reason" 'python3 -c "
import json, sys
s = json.load(open(sys.argv[1]))[\"skipped\"]
sys.exit(0 if [r[\"name\"] for r in s] == [\"Areola\"] and s[0][\"reason\"] == \"no contours\" else 1)" "$T/out"'
$S volume "$C/dicompyler-core_example_rtss.dcm" --roi Areola >/dev/null 2>"$T/err"; rc=$?
check "... and --roi naming it: refused with the reason" '[ $rc -ne 0 ] && grep -q "nothing to model: no contours" "$T/err"'
$S model "$C/dicompyler-core_example_rtss.dcm" --caps slab --mesh "$T/rois/" >"$T/out" 2>"$T/err"
check "surfd model RS.dcm --mesh DIR/: the directory made, every ROI's closed mesh, DIR/NAME.stl" '[ $? -eq 0 ] && [ "$(ls "$T/rois" | wc -l)" = 9 ] && [ -f "$T/rois/Tumor_Bed_Block.stl" ] && for f in "$T"/rois/*.stl; do python3 tests/tools/stl_check.py "$f" - >/dev/null || exit 1; done'
$S model "$C/dicompyler-core_example_rtss.dcm" --roi Heart --mesh "$T/none/rois/" >/dev/null 2>"$T/err"; rc=$?
check "--mesh DIR/ whose parent is missing: refused, naming the directory" '[ $rc -ne 0 ] && grep -q "cannot make $T/none/rois/" "$T/err"'
$S volume 2>/dev/null; rc=$?
check "usage" '[ $rc -eq 2 ]'
checks_done
