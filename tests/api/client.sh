#!/bin/sh
# The README's curl examples (client/examples) and surfctl against a real daemon with tokens:
# outputs, exit codes, SURFD_URL, SURFD_TOKEN and a TLS daemon signed by a site's own CA (--cacert,
# SURFD_CACERT, the Python client's cafile=).
. "$(dirname "$0")/lib.inc"
C=./build/surfctl
printf 'tok-for-tests\n' >"$T/tokens"; chmod 600 "$T/tokens"
start_daemon "$T/d" --token-file "$T/tokens" --sync-wait 5 || exit 1
export SURFD_URL="$URL" SURFD_TOKEN=tok-for-tests

client/examples/render_sync.sh "$D/teapot.json" "$T/a.png"
check "example render_sync" '[ $? -eq 0 ] && [ "$(head -c 4 "$T/a.png" | od -An -tx1 | tr -d " \n")" = 89504e47 ]'
client/examples/render_async.sh "$D/duck2.nurbs" "$T/b.png"
check "example render_async" '[ $? -eq 0 ] && [ -s "$T/b.png" ]'
client/examples/render_exr_depth.sh "$D/teapot.bpt" "$T/c.exr"
check "example render_exr_depth: the EXR holds Z and the AOVs it claims (N.x, u, id)" '[ $? -eq 0 ] && head -c 3000 "$T/c.exr" | grep -aq "N.x" && head -c 3000 "$T/c.exr" | grep -aq "id" && head -c 3000 "$T/c.exr" | grep -aq "Z"'
check "example bad_scene" 'client/examples/bad_scene.sh | grep -q "\"pointer\":\"/objects/0/knots_u/2\"" && client/examples/bad_scene.sh | tail -n 1 | grep -q 422'
check "example health" 'client/examples/health.sh | grep -q surfd_queue_depth'
client/examples/model_mesh.sh "${SURFD_DATA:-../shared/data}/contours/synthetic_ellipsoid.json" "$T/m.stl" --caps dome >"$T/out" 2>/dev/null
vol=$(sed 's/.*"volume_mm3":\([0-9.]*\).*/\1/' "$T/out")
check "example model_mesh" '[ $? -eq 0 ] && grep -q "\"caps\":\"dome\"" "$T/out" && python3 tests/tools/stl_check.py "$T/m.stl" "$vol" >/dev/null'
client/examples/model_mesh.sh "${SURFD_DATA:-../shared/data}/contours/dicompyler-core_example_rtss.dcm" "$T/h.obj" --roi Heart >"$T/out" 2>/dev/null
check "example model_mesh of an RTSTRUCT ROI" '[ $? -eq 0 ] && grep -q "\"name\":\"Heart\"" "$T/out" && grep -q "^f " "$T/h.obj"'
client/examples/model_mesh.sh "${SURFD_DATA:-../shared/data}/contours/dicompyler-core_example_rtss.dcm" "$T/all.stl" --caps slab >"$T/out" 2>"$T/files"
check "example model_mesh of a whole RTSTRUCT: every ROI, a closed mesh each, named by its ROI" '[ $? -eq 0 ] && [ "$(wc -l <"$T/files")" -gt 1 ] && [ -f "$T/all_Heart.stl" ] && while read -r f; do python3 tests/tools/stl_check.py "$f" - >/dev/null || exit 1; done <"$T/files"'

$C model "${SURFD_DATA:-../shared/data}/contours/synthetic_ellipsoid.json" >"$T/mres" 2>/dev/null
mid=$(python3 -c "import json, sys; print(json.load(open(sys.argv[1]))['id'])" "$T/mres" 2>/dev/null)
$C rtstruct "$mid" -o "$T/e.dcm" --spacing 5 2>/dev/null; rc=$?
check "surfctl rtstruct ID -o OUT --spacing: a DICOM RT Structure Set" '[ $rc -eq 0 ] && [ "$(dd if="$T/e.dcm" bs=1 skip=128 count=4 2>/dev/null)" = DICM ] && grep -aq RTSTRUCT "$T/e.dcm"'
$C rtstruct "$mid" 2>/dev/null; rc=$?
check "surfctl rtstruct without -o exits 2" '[ $rc -eq 2 ]'
$C patches "$mid" >"$T/p.json" 2>/dev/null; rc=$?
check "surfctl patches ID: the model's scene on stdout" '[ $rc -eq 0 ] && python3 -c "import json, sys; sys.exit(not json.load(open(sys.argv[1]))[\"objects\"])" "$T/p.json"'
DD="${SURFD_DATA:-../shared/data}/volumes/dicom_ct_head_64x64x27"
parts=""; for f in "$DD"/*; do parts="$parts -F slice=@$f"; done
# shellcheck disable=SC2086
curl -s -H "Authorization: Bearer tok-for-tests" $parts "$URL/isosurface?iso=226.5" >"$T/curl_series.json"
# same_series FILE: the model FILE holds is the one curl -F's upload of the series made
same_series() { python3 -c "
import json, sys
a, b = json.load(open(sys.argv[1])), json.load(open(sys.argv[2]))
sys.exit(0 if a['triangles'] == b['triangles'] and abs(a['volume_mm3'] / b['volume_mm3'] - 1) < 1e-9 else 1)" "$1" "$T/curl_series.json"; }
$C isosurface "$DD" --iso 226.5 -o "$T/series.stl" >"$T/out" 2>/dev/null; rc=$?
check "surfctl isosurface DICOM-DIR: the series uploaded (a part a file), curl -F's model, its mesh closed" '[ $rc -eq 0 ] && same_series "$T/out" && python3 tests/tools/stl_check.py "$T/series.stl" - >/dev/null'
check "the Python client's isosurface(DICOM-DIR): the same" 'PYTHONPATH=client/python python3 -c "
import json, surfd, sys
json.dump(surfd.Client().isosurface(sys.argv[1], iso=226.5), open(sys.argv[2], \"w\"))" "$DD" "$T/py_series.json" && same_series "$T/py_series.json"'
mkdir -p "$T/export"; cp "$DD"/* "$T/export/"; cp "$DD/$(ls "$DD" | head -n 1)" "$T/export/DICOMDIR"; echo "export notes" >"$T/export/README.txt"
$C isosurface "$T/export" --iso 226.5 -o "$T/export.stl" >"$T/out" 2>"$T/err"; rc=$?
check "surfctl isosurface of an export's directory (a DICOMDIR, a README beside the images): the images alone, the same model" '[ $rc -eq 0 ] && same_series "$T/out" && grep -q "README.txt is not an image" "$T/err"'
check "... and the Python client's" 'PYTHONPATH=client/python python3 -c "
import json, surfd, sys
json.dump(surfd.Client().isosurface(sys.argv[1], iso=226.5), open(sys.argv[2], \"w\"))" "$T/export" "$T/py_export.json" && same_series "$T/py_export.json"'
$C render "$D/teacup.json" -o "$T/d.png" --width 120 --height 90
check "surfctl render" '[ $? -eq 0 ] && [ -s "$T/d.png" ]'
id=$($C render "$D/duck1.nurbs" --async --width 200 --height 150)
check "surfctl render --async prints the id" '[ $? -eq 0 ] && echo "$id" | grep -qE "^[0-9a-f]{32}$"'
$C wait "$id" -o "$T/e.png" 2>"$T/progress"
check "surfctl wait -o" '[ $? -eq 0 ] && [ -s "$T/e.png" ]'
check "surfctl job" '$C job "$id" | grep -q "\"state\":\"succeeded\""'
check "surfctl jobs --state" '$C jobs --state succeeded | grep -q "$id"'
$C result "$id" -o "$T/f.png"
check "surfctl result" '[ $? -eq 0 ] && cmp -s "$T/e.png" "$T/f.png"'
CT="${SURFD_DATA:-../shared/data}/volumes/ct_head_crop64_int16.raw"
$C isosurface "$CT" --iso 226.5 --dims 64,64,64 --type int16 --spacing 0.9570312,0.9570312,1.5 -o "$T/ct.stl" >"$T/out" 2>"$T/progress"
check "surfctl isosurface: the model on stdout, its closed mesh in the file" '[ $? -eq 0 ] && grep -q "\"source\":\"isosurface\"" "$T/out" && python3 tests/tools/stl_check.py "$T/ct.stl" 57529.6 >/dev/null'
$C isosurface "$CT" --iso 226.5 --dims 64,64,64 --type int16 --spacing 0.9570312,0.9570312,1.5 --levels 3 --max-error 1 -o "$T/ct3.stl" >"$T/out" 2>"$T/progress"
check "surfctl isosurface --levels 3 --max-error 1: coarser, closed" '[ $? -eq 0 ] && grep -q "\"levels\":3" "$T/out" && python3 tests/tools/stl_check.py "$T/ct3.stl" "$(python3 -c "import json,sys; print(json.load(open(sys.argv[1]))[\"volume_mm3\"])" "$T/out")" >/dev/null'
printf '{"bounds": [[-1.2, -1.2, -1.2], [1.2, 1.2, 1.2]], "cell": 0.05, "frep": {"torus": {"center": [0, 0, 0], "axis": [0, 0, 1], "major": 0.8, "minor": 0.3}}}' >"$T/torus.json"
mid=$(python3 -c "import json,sys; print(json.load(open(sys.argv[1]))['id'])" "$T/out")
python3 tests/tools/edit_tool.py block 8 1400 -100 3 "$T/blk.raw"
$C edit "$mid" "$T/blk.raw" --region 20,24,17,8,8,8 -o "$T/ct3e.stl" >"$T/out" 2>"$T/err"
check "surfctl edit: the edited model on stdout (edits 1), its closed mesh in the file" '[ $? -eq 0 ] && grep -q "\"edits\":1" "$T/out" && python3 tests/tools/stl_check.py "$T/ct3e.stl" "$(python3 -c "import json,sys; print(json.load(open(sys.argv[1]))[\"volume_mm3\"])" "$T/out")" >/dev/null'
$C edit "$mid" "$T/blk.raw" --region 60,24,17,8,8,8 >"$T/out" 2>"$T/err"; rc=$?
check "surfctl edit of a region past the volume exits 4 naming ?region" '[ $rc -eq 4 ] && grep -q "?region" "$T/err"'
$C isosurface "$T/torus.json" -o "$T/torus.stl" >"$T/out" 2>"$T/progress"
check "surfctl isosurface of an FRep .json: a closed torus" '[ $? -eq 0 ] && grep -q "\"source\":\"frep\"" "$T/out" && grep -q "\"euler_characteristic\":0" "$T/out"'
printf '{"bounds": [[-1.2, -1.2, -1.2], [1.2, 1.2, 1.2]], "cell": 0.05, "frep": {"transform": {"rotate_deg": [20, 30, 10], "object": {"box": {"min": [-0.8, -0.6, -0.5], "max": [0.8, 0.6, 0.5]}}}}}' >"$T/box.json"
$C isosurface "$T/box.json" --features sharp -o "$T/box.stl" >"$T/out" 2>"$T/progress"
check "surfctl isosurface --features sharp: a turned box with its feature points, its volume within 0.05 %" '[ $? -eq 0 ] && python3 -c "
import json, sys
m = json.load(open(sys.argv[1]))
sys.exit(0 if m[\"features\"] == \"sharp\" and m[\"feature_points\"] > 0 and abs(m[\"volume_mm3\"] / 1.92 - 1) < 5e-4 else 1)" "$T/out"'
$C isosurface "$CT" --dims 64,64,64 --type int16 -o "$T/x.stl" 2>"$T/err"; rc=$?
check "surfctl isosurface without --iso exits 4 naming ?iso" '[ $rc -eq 4 ] && grep -q "?iso" "$T/err"'
$C render "$D/teapot.json" -o "$T/g.png" --width 0 2>"$T/err"; rc=$?
check "surfctl 4xx exits 4 with the pointer" '[ $rc -eq 4 ] && grep -q "?width" "$T/err"'
$C cancel "$id" 2>/dev/null; rc=$?
check "surfctl cancel of an ended job exits 4" '[ $rc -eq 4 ]'
$C job 0123456789abcdef0123456789abcdef 2>/dev/null; rc=$?
check "surfctl unknown job exits 4" '[ $rc -eq 4 ]'
SURFD_TOKEN=wrong $C jobs 2>/dev/null; rc=$?
check "surfctl wrong token exits 4" '[ $rc -eq 4 ]'
$C bogus 2>/dev/null; rc=$?
check "surfctl usage exits 2" '[ $rc -eq 2 ]'
stop_daemon
$C jobs 2>/dev/null; rc=$?
check "surfctl daemon down exits 3" '[ $rc -eq 3 ]'

# the shipped config file is valid as it is
start_daemon "$T/d2" --config deploy/surfd.conf --listen 127.0.0.1:0 || exit 1
check "deploy/surfd.conf loads" 'alive'
stop_daemon

# a daemon whose certificate a site's own certificate authority signed
openssl req -x509 -newkey rsa:2048 -nodes -keyout "$T/ca.key" -out "$T/ca.pem" -days 1 -subj /CN=surfd-test-CA >/dev/null 2>&1
openssl req -newkey rsa:2048 -nodes -keyout "$T/key.pem" -out "$T/req.pem" -subj /CN=127.0.0.1 >/dev/null 2>&1
printf 'subjectAltName=IP:127.0.0.1\n' >"$T/san"
openssl x509 -req -in "$T/req.pem" -CA "$T/ca.pem" -CAkey "$T/ca.key" -CAcreateserial -out "$T/cert.pem" -days 1 \
    -extfile "$T/san" >/dev/null 2>&1
start_daemon "$T/d3" --tls-cert "$T/cert.pem" --tls-key "$T/key.pem" || exit 1
SURFD_URL=$URL $C models >/dev/null 2>&1; rc=$?
check "surfctl to a TLS daemon of a CA it does not know exits 3" '[ $rc -eq 3 ]'
SURFD_URL=$URL $C --cacert "$T/ca.pem" models >/dev/null 2>&1; rc=$?
check "surfctl --cacert CA: the daemon's answer" '[ $rc -eq 0 ]'
SURFD_URL=$URL SURFD_CACERT="$T/ca.pem" $C models >/dev/null 2>&1; rc=$?
check "SURFD_CACERT=CA: the same" '[ $rc -eq 0 ]'
check "the Python client's cafile=: the daemon's version" 'PYTHONPATH=client/python python3 -c "import surfd, sys; sys.exit(surfd.Client(sys.argv[1], token=\"\", cafile=sys.argv[2]).version()[\"name\"] != \"surfd\")" "$URL" "$T/ca.pem"'
check "... and without it, surfd unreachable (status 0) naming the certificate" 'PYTHONPATH=client/python python3 -c "
import surfd, sys
try:
    surfd.Client(sys.argv[1], token=\"\").version()
except surfd.SurfdError as e:
    sys.exit(not (e.status == 0 and \"CERTIFICATE\" in str(e).upper()))
sys.exit(1)" "$URL"'
finish
