#!/bin/sh
# Sparse and polygonal contours measured as drawn (issue 47: 2): what a planning system draws with 4
# to 8 points a slice (a couch, an L-shaped block, a box with points midway along its edges) is the
# prism of its polygons over HTTP, through surfctl and in an RT Structure Set (it was +39.9 %, +43 %
# and +8.3 %), its mesh never outside the polygon; a contour short of corners (an octagon) is a curve
# whose figures warn that it encloses more than its polygons, with the polygons' volume beside it;
# a densely outlined organ keeps the curve's (the ellipse's volume within 1e-4).
. "$(dirname "$0")/lib.inc"
PY=/usr/bin/python3 # Debian's: pydicom, numpy
$PY -c "import pydicom, numpy" 2>/dev/null || { bad "python3-pydicom or python3-numpy is missing (deploy/install-deps.sh installs them)"; checks_done; exit 1; }
DCM='Content-Type: application/dicom'
J='Content-Type: application/json'
$PY tests/tools/dicom_write.py rtstruct "$T/sparse.dcm"
# roi FIELD...: the named ROI's figures from $T/body (a list of models)
# (a lone model's figures when the body is one), a list's members' fields as JSON lists
roi() { $PY -c "
import json, sys
d = json.load(open(sys.argv[1]))
m = [m for m in d.get('models', [d]) if m['name'] == sys.argv[2]][0]
for f in sys.argv[3:]:
    v = m
    for k in f.split('.'):
        v = v[k] if isinstance(v, dict) else [w[k] for w in v]
    print(json.dumps(v) if isinstance(v, list) else v)" "$T/body" "$@"; }
near() { $PY -c "import sys; sys.exit(0 if abs(float(sys.argv[1]) / float(sys.argv[2]) - 1) <= float(sys.argv[3]) else 1)" "$@"; }
start_daemon "$T/d" || exit 1

code=$(status POST /volume -H "$DCM" --data-binary @"$T/sparse.dcm")
check "POST /volume of an RT Structure Set of sparse ROIs: 200, one figure set per ROI" '[ "$code" = 200 ] && [ "$($PY -c "import json,sys; print(len(json.load(open(sys.argv[1]))[\"models\"]))" "$T/body")" = 5 ]'
for r in Couch:720000 Block:10800 Box:15000; do
    name=${r%%:*} prism=${r#*:}
    check "$name: the prism's volume (area x 6 mm, flat caps) to 1e-9, no warning" 'near "$(roi "$name" volume_mm3)" "$prism" 1e-9 && [ "$(roi "$name" warnings 2>/dev/null)" = "" ]'
done
check "Octagon: a curve, warned: curves-depart-from-polygons, by about 9.7 %, the polygons' volume beside it" '[ "$(roi Octagon warnings.code)" = "[\"curves-depart-from-polygons\"]" ] && $PY -c "import json, sys; sys.exit(0 if 0.05 < json.loads(sys.argv[1])[0] < 0.15 else 1)" "$(roi Octagon warnings.departure)" && near "$(roi Octagon volume.trapezoid)" 15273.504 1e-6 && roi Octagon warnings.message | grep -q "polygons"'
check "Organ (an ellipse of 72 points): the curve's volume, within 1e-4 of the true ellipse's prism, no warning" 'near "$(roi Organ volume_mm3)" "$($PY -c "import math; print(math.pi * 60 * 40 * 6)")" 1e-4 && [ "$(roi Organ warnings 2>/dev/null)" = "" ]'

code=$(status POST "/model?roi=Couch" -H "$DCM" --data-binary @"$T/sparse.dcm"); id=$(roi Couch id)
code=$(status GET "/models/$id/mesh?format=stl"); cp "$T/body" "$T/couch.stl"
check "the couch's mesh: its volume the prism's, no vertex outside the 400 x 300 mm rectangle or its slices" '[ "$code" = 200 ] && $PY -c "
import struct, sys
d = open(sys.argv[1], \"rb\").read(); n = struct.unpack_from(\"<I\", d, 80)[0]; vol = 0.0; out = 0.0
for t in range(n):
    v = [struct.unpack_from(\"<3f\", d, 84 + 50 * t + 12 * (k + 1)) for k in range(3)]
    a, b, c = v
    vol += (a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) + a[2] * (b[0] * c[1] - b[1] * c[0])) / 6
    for p in v:
        out = max(out, abs(p[0]) - 200, abs(p[1]) - 150, -p[2], p[2] - 6)
sys.exit(0 if abs(vol / 720000 - 1) < 1e-5 and out < 1e-3 else 1)" "$T/couch.stl"'

printf '{"name": "square", "slices": [%s]}' "$(for z in 0 3 6 9 12 15 18 21 24 27; do printf '%s{"z": %s, "points": [[0, 0], [50, 0], [50, 50], [0, 50]]}' "$([ $z = 0 ] || echo ,)" $z; done)" >"$T/square.json"
code=$(status POST /volume -H "$J" --data-binary @"$T/square.json")
check "contour JSON: a 50 mm square of 4 points on 10 slices 3 mm apart, the prism's 67500 mm3 (was 92250)" '[ "$code" = 200 ] && near "$($PY -c "import json,sys; print(json.load(open(sys.argv[1]))[\"volume_mm3\"])" "$T/body")" 67500 1e-9'
SURFD_URL="$URL" ./build/surfctl volume "$T/sparse.dcm" --roi Block >"$T/body" 2>"$T/err"
check "surfctl volume --roi Block: the prism's 10800 mm3" 'near "$(roi Block volume_mm3)" 10800 1e-9'
finish
