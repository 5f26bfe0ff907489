#!/bin/sh
# Black-box tests of the model routes as curl users drive them: POST /model (contour JSON and RT
# Structure Sets, sync and async), GET /models and /models/{id}, meshes (a closed STL holding the
# model's volume, PLY, OBJ), patches that /render takes back, /models/{id}/render, stored models as
# scene objects, DELETE, every error as problem+json, models surviving a restart and a kill -9.
. "$(dirname "$0")/lib.inc"
C="${SURFD_DATA:-../shared/data}/contours"
J='Content-Type: application/json'
field() { sed -n "s/.*\"$1\":\"\\([^\"]*\\)\".*/\\1/p" "$T/body" | head -n 1; }

start_daemon "$T/m1" --threads 2 || exit 1

# ---- POST /model, GET /models/{id}, GET /models ------------------------------------------------
code=$(status POST /model -H "$J" --data-binary @"$C/synthetic_bean.json")
id=$(field id); loc=$(header Location)
check "model 201 with Location" '[ "$code" = 201 ] && [ "$loc" = "/models/$id" ] && grep -q "\"volume_mm3\":665[0-9][0-9]\." "$T/body" && grep -q "\"mesh\":\"/models/$id/mesh?format=stl\"" "$T/body"'
vol=$(sed 's/.*"volume_mm3":\([0-9.]*\).*/\1/' "$T/body")
check "GET the model" '[ "$(status GET "$loc")" = 200 ] && grep -q "\"id\":\"$id\"" "$T/body" && grep -q "\"caps\":\"flat\"" "$T/body"'
etag=$(header ETag)
check "GET the model again: 304 on its ETag" '[ -n "$etag" ] && [ "$(status GET "$loc" -H "If-None-Match: $etag")" = 304 ]'
check "GET /models lists it" '[ "$(status GET /models)" = 200 ] && grep -q "\"models\":\[{" "$T/body" && grep -q "\"id\":\"$id\"" "$T/body"'
code=$(status POST "/model?caps=dome" -H "$J" --data-binary @"$C/synthetic_ellipsoid.json")
dome=$(field id); domevol=$(python3 -c "import json,sys; print(json.load(open(sys.argv[1]))['volume_mm3'])" "$T/body")
check "model ?caps=dome" '[ "$code" = 201 ] && grep -q "\"caps\":\"dome\"" "$T/body" && grep -q "\"dome_ends_flat\":0" "$T/body"'
code=$(status POST /model -H 'Content-Type: application/dicom' --data-binary @"$C/slicerrt_EclipseProstatePhantom_RS.dcm")
ids=$(grep -o '"id":"[0-9a-f]*"' "$T/body" | cut -d'"' -f4 | sort -u)
check "model from an RT Structure Set: one model per ROI" '[ "$code" = 201 ] && grep -q "\"models\":\[" "$T/body" && [ "$(echo "$ids" | wc -l)" -ge 5 ]'
n=0; for m in $ids; do [ "$(status GET /models/$m)" = 200 ] && n=$((n + 1)); done
check "every ROI's model is stored" '[ "$n" -eq "$(echo "$ids" | wc -l)" ]'
code=$(status POST /model -H 'Prefer: respond-async' -H "$J" --data-binary @"$C/eclipse_ptv.json")
job=$(header X-Job-Id)
check "model async: 202, then the result as POST would have sent it" '[ "$code" = 202 ] && wait_state "$job" succeeded && [ "$(status GET /jobs/$job/result)" = 201 ] && [ "$(header Location)" = "/models/$job" ] && [ "$(status GET /models/$job)" = 200 ]'

code=$(status POST "/model?method=bspline&caps=slab" -H "$J" --data-binary @"$C/synthetic_torus_branching.json")
bs=$(field id); bsvol=$(sed 's/.*"volume_mm3":\([0-9.]*\).*/\1/' "$T/body")
check "model ?method=bspline" '[ "$code" = 201 ] && grep -q "\"method\":\"bspline\"" "$T/body" && [ "$(status GET "/models/$bs/mesh")" = 200 ] && python3 tests/tools/stl_check.py "$T/body" "$bsvol" >/dev/null'
check "model ?parameterisation=polar, kept with the model" '[ "$(status POST "/model?parameterisation=polar" -H "$J" --data-binary @"$C/synthetic_ellipsoid.json")" = 201 ] && grep -q "\"parameterisation\":\"polar\"" "$T/body" && pid=$(field id) && [ "$(status GET "/models/$pid/patches")" = 200 ]'
check "model 422 ?parameterisation" '[ "$(status POST "/model?parameterisation=spiral" -H "$J" --data-binary @"$C/synthetic_bean.json")" = 422 ] && grep -q "\"pointer\":\"?parameterisation\"" "$T/body"'
check "model 422 ?method" '[ "$(status POST "/model?method=nurbs" -H "$J" --data-binary @"$C/synthetic_bean.json")" = 422 ] && grep -q "\"pointer\":\"?method\"" "$T/body"'

# ---- meshes and patches ---------------------------------------------------------------------
code=$(status GET "/models/$id/mesh?format=stl")
cp "$T/body" "$T/m.stl"
check "mesh STL: closed, holding the model's volume" '[ "$code" = 200 ] && [ "$(header Content-Type)" = model/stl ] && python3 tests/tools/stl_check.py "$T/m.stl" "$vol" >/dev/null'
check "mesh STL is the default" '[ "$(status GET "/models/$id/mesh")" = 200 ] && cmp -s "$T/body" "$T/m.stl"'
check "mesh PLY" '[ "$(status GET "/models/$id/mesh?format=ply&tolerance=0.2")" = 200 ] && head -c 40 "$T/body" | grep -q "binary_little_endian"'
code=$(status GET "/models/$id/mesh?format=vtp&tolerance=0.2"); cp "$T/body" "$T/m.vtp"
check "mesh VTP: VTK reads it, closed" '[ "$code" = 200 ] && /usr/bin/python3 tests/tools/vtk_check.py "$T/m.vtp" | grep -q "\"boundary_edges\": 0"'
code=$(status GET "/models/$id/mesh?format=vtk&tolerance=0.2"); cp "$T/body" "$T/m.vtk"
check "mesh legacy VTK: VTK reads it, closed" '[ "$code" = 200 ] && /usr/bin/python3 tests/tools/vtk_check.py "$T/m.vtk" | grep -q "\"boundary_edges\": 0"'
check "mesh OBJ" '[ "$(status GET "/models/$id/mesh?format=obj&tolerance=0.2")" = 200 ] && grep -q "^v " "$T/body" && grep -q "^f " "$T/body"'
check "mesh 422 format" '[ "$(status GET "/models/$id/mesh?format=vrml")" = 422 ] && grep -q "\"pointer\":\"?format\"" "$T/body"'
check "mesh 422 for a tolerance that would make too many triangles" '[ "$(status GET "/models/$id/mesh?tolerance=0.00001")" = 422 ] && grep -q "\"pointer\":\"?tolerance\"" "$T/body" && grep -q "triangles" "$T/body"'
check "mesh 422 tolerance" '[ "$(status GET "/models/$id/mesh?tolerance=abc")" = 422 ] && grep -q "\"pointer\":\"?tolerance\"" "$T/body" && [ "$(status GET "/models/$id/mesh?tolerance=-1")" = 422 ]'
code=$(status GET "/models/$dome/patches")
cp "$T/body" "$T/p.json"
check "patches: bicubic and rational dome patches" '[ "$code" = 200 ] && grep -q "\"type\":\"bezier\"" "$T/p.json" && grep -q "\"type\":\"nurbs\"" "$T/p.json"'
check "patches posted back to POST /volume: closed (edges meeting parts of others), the model's volume" '[ "$(status POST /volume -H "$J" --data-binary @"$T/p.json")" = 200 ] && grep -q "\"closed\":true" "$T/body" && python3 -c "import json,sys; v=json.load(open(sys.argv[1]))[\"volume_mm3\"]; sys.exit(abs(v/float(sys.argv[2])-1)>1e-6 or abs(v/125663.7-1)>5e-4)" "$T/body" "$domevol"'
# clinical structures: patches between slices whose corresponding points nearly coincide are slivers,
# their opposite edges within the matching tolerance of each other (the bladder has some)
for f in eclipse_bladder eclipse_ptv dicompyler_tumor_bed; do
    status POST "/model?caps=dome" -H "$J" --data-binary @"$C/$f.json" >/dev/null
    mid=$(field id); mvol=$(python3 -c "import json,sys; print(json.load(open(sys.argv[1]))['volume_mm3'])" "$T/body")
    status GET "/models/$mid/patches" >/dev/null && cp "$T/body" "$T/cp.json"
    check "$f: its patches posted back to POST /volume close with the model's volume" '[ "$(status POST /volume -H "$J" --data-binary @"$T/cp.json")" = 200 ] && grep -q "\"closed\":true" "$T/body" && python3 -c "import json,sys; v=json.load(open(sys.argv[1]))[\"volume_mm3\"]; sys.exit(abs(v/float(sys.argv[2])-1)>1e-6)" "$T/body" "$mvol"'
done
code=$(status POST /model -H "$J" --data-binary @"$C/synthetic_torus_branching.json"); tid=$(field id)
[ "$code" = 201 ] && status GET "/models/$tid/patches" >/dev/null && cp "$T/body" "$T/tp.json"
[ "$code" = 201 ] && status GET "/models/$tid" >/dev/null && tvol=$(python3 -c "import json,sys; print(json.load(open(sys.argv[1]))['volume_mm3'])" "$T/body")
check "a branching model's patches: the planes where tubes end and begin as trimmed flat patches" 'python3 -c "import json,sys; o=json.load(open(sys.argv[1]))[\"objects\"]; t=[x for x in o if \"trim\" in x]; sys.exit(not (len(t) == 4 and all(x[\"degree\"] == [1, 1] for x in t)))" "$T/tp.json"'
check "... posted back to POST /volume: one closed solid, none turned, the model's volume" '[ "$(status POST /volume -H "$J" --data-binary @"$T/tp.json")" = 200 ] && grep -q "\"closed\":true" "$T/body" && grep -q "\"surfaces_turned\":0" "$T/body" && python3 -c "import json,sys; v=json.load(open(sys.argv[1]))[\"volume_mm3\"]; sys.exit(abs(v/float(sys.argv[2])-1)>1e-6)" "$T/body" "$tvol"'
check "... rendered as a scene" '[ "$(status POST "/render?width=64&height=48" -H "$J" --data-binary @"$T/tp.json")" = 200 ] && [ "$(header Content-Type)" = image/png ]'
check "patches render as a scene" '[ "$(status POST "/render?width=64&height=48" -H "$J" --data-binary @"$T/p.json")" = 200 ] && [ "$(header Content-Type)" = image/png ]'

check "a mesh is a job of its own kind" '[ "$(status GET "/models/$id/mesh?tolerance=0.5")" = 200 ] && mj=$(header X-Job-Id) && [ "$(status GET /jobs/$mj)" = 200 ] && grep -q "\"kind\":\"mesh\"" "$T/body"'
code=$(status POST /volume -H 'Content-Type: application/dicom' --data-binary @"$C/dicompyler-core_example_rtss.dcm")
check "an RT Structure Set's ROIs without contours are listed as skipped, with the reason" '[ "$code" = 200 ] && grep -q "\"skipped\":\[{\"name\":\"Areola\",\"roi_number\":2,\"reason\":\"no contours\"}\]" "$T/body"'
code=$(status POST "/volume?roi=Areola" -H 'Content-Type: application/dicom' --data-binary @"$C/dicompyler-core_example_rtss.dcm")
check "... ?roi naming one: 422 at ?roi with the reason" '[ "$code" = 422 ] && grep -q "\"pointer\":\"?roi\"" "$T/body" && grep -q "no contours" "$T/body"'
status POST "/model?roi=Heart" -H 'Content-Type: application/dicom' --data-binary @"$C/dicompyler-core_example_rtss.dcm" >/dev/null
heart=$(field id)
pids=""
for k in 1 2 3; do
    curl -s -o /dev/null "$URL/models/$heart/mesh?tolerance=0.005" &
    pids="$pids $!"
done
sleep 0.3
check "the HTTP threads stay free while meshes are built" '[ "$(curl -s -m 1 -o /dev/null -w "%{http_code}" "$URL/livez")" = 200 ] && [ "$(curl -s -m 1 -o /dev/null -w "%{http_code}" "$URL/models/$id")" = 200 ]'
wait $pids

# ---- rendering stored models --------------------------------------------------------------------
check "GET /models/{id}/render" '[ "$(status GET "/models/$id/render?width=80&height=60&azimuth=60")" = 200 ] && [ "$(header Content-Type)" = image/png ] && [ -n "$(header X-Job-Id)" ]'
check "a model object in a scene" '[ "$(status POST "/render?width=64&height=48" -H "$J" --data-binary "{\"objects\":[{\"type\":\"model\",\"id\":\"$id\",\"material\":{\"color\":[0.9,0.4,0.3]}}]}")" = 200 ]'
check "422 unknown model in a scene" '[ "$(status POST /render -H "$J" --data-binary "{\"objects\":[{\"type\":\"model\",\"id\":\"0123456789abcdef\"}]}")" = 422 ] && grep -q "\"pointer\":\"/objects/0/id\"" "$T/body"'
check "422 model object without id" '[ "$(status POST /render -H "$J" --data-binary "{\"objects\":[{\"type\":\"model\"}]}")" = 422 ] && grep -q "\"pointer\":\"/objects/0/id\"" "$T/body"'
check "422 model material" '[ "$(status POST /render -H "$J" --data-binary "{\"objects\":[{\"type\":\"model\",\"id\":\"$id\",\"material\":{\"color\":[1,1]}}]}")" = 422 ] && grep -q "/objects/0/material" "$T/body"'

# ---- trimmed patches in a JSON scene -------------------------------------------------------------
# a flat unit square seen from above, whole and trimmed to a disk of radius 0.4 (64 points): pi 0.16
flat() { printf '{"objects":[{"degree":[1,1],"points":[[0,0,0],[0,1,0],[1,0,0],[1,1,0]]%s}]}' "$1"; }
DISK=$(python3 -c "import math; print([[0.5 + 0.4 * math.cos(math.pi * k / 32), 0.5 + 0.4 * math.sin(math.pi * k / 32)] for k in range(64)])")
VIEW="/render?width=128&height=128&eye=0.5,0.5,3&target=0.5,0.5,0&up=0,1,0&fov=30"
status POST "$VIEW" -H "$J" --data-binary "$(flat "")" >/dev/null && cp "$T/body" "$T/whole.png"
code=$(status POST "$VIEW" -H "$J" --data-binary "$(flat ",\"trim\":[$DISK]")")
check "a patch trimmed to a disk draws the disk: pi 0.16 of the square's pixels" '[ "$code" = 200 ] && cp "$T/body" "$T/disk.png" && python3 -c "import sys; r=float(sys.argv[2])/float(sys.argv[1]); sys.exit(abs(r-0.5027)>0.02)" "$(python3 tests/tools/png_cover.py "$T/whole.png")" "$(python3 tests/tools/png_cover.py "$T/disk.png")"'
code=$(status POST "$VIEW" -H "$J" --data-binary "$(flat ",\"trim\":[$DISK,[[0.4,0.4],[0.6,0.4],[0.6,0.6],[0.4,0.6]]]")")
check "... with a square hole (even-odd): fewer pixels" '[ "$code" = 200 ] && python3 -c "import sys; sys.exit(not 0 < float(sys.argv[2]) < float(sys.argv[1]))" "$(python3 tests/tools/png_cover.py "$T/disk.png")" "$(python3 tests/tools/png_cover.py "$T/body")"'
for bad in '5|/objects/0/trim' '[]|/objects/0/trim' '[[[0,0],[1,0]]]|/objects/0/trim/0' '[[[0,0],[1,0],[2,1]]]|/objects/0/trim/0/2' \
           '[[[0,0],[1,0],["a",1]]]|/objects/0/trim/0/2/0' '[[[0,0],[1,0],[1]]]|/objects/0/trim/0/2' \
           '[[[0,0],[0.5,0],[1,0]]]|/objects/0/trim'; do
    trim=${bad%|*} ptr=${bad#*|}
    code=$(status POST "$VIEW" -H "$J" --data-binary "$(flat ",\"trim\":$trim")")
    check "trim $trim: 422 at $ptr" '[ "$code" = 422 ] && is_problem 422 && grep -q "\"pointer\":\"$ptr\"" "$T/body"'
done
check "the daemon is up after the bad trims" '[ "$(status GET /livez)" = 200 ]'

# ---- POST /volume of a scene whose patches close ---------------------------------------------------
printf '{"objects":[' >"$T/cube.json"
sep=""
for f in "0,0,0 0,1,0 1,0,0" "0,0,1 1,0,0 0,1,0" "0,0,0 1,0,0 0,0,1" "0,1,0 0,0,1 1,0,0" "0,0,0 0,0,1 0,1,0" "1,0,0 0,1,0 0,0,1"; do
    set -- $f
    o=$1; a=$2; b=$3
    pts=$(python3 -c "o,a,b=[[float(x) for x in s.split(',')] for s in '$o $a $b'.split()]
print(','.join('[%g,%g,%g]' % tuple(o[c]+i*a[c]+j*b[c] for c in range(3)) for i in (0,1) for j in (0,1)))")
    printf '%s{"degree":[1,1],"points":[%s]}' "$sep" "$pts" >>"$T/cube.json"; sep=","
done
printf ']}' >>"$T/cube.json"
check "volume of a closed scene (a unit cube of six patches)" '[ "$(status POST /volume -H "$J" --data-binary @"$T/cube.json")" = 200 ] && grep -q "\"volume_mm3\":1[,.]" "$T/body" && grep -q "\"closed\":true" "$T/body"'
check "volume of the open teapot: 422 at an object" '[ "$(status POST /volume -H "Content-Type: model/x-bpt" --data-binary @"${SURFD_DATA:-../shared/data}/scenes/teapot.bpt")" = 422 ] && grep -q "\"pointer\":\"/objects/[0-9]*\"" "$T/body" && grep -q "closed solid" "$T/body"'
check "model of a JSON scene: 422" '[ "$(status POST /model -H "$J" --data-binary @"$T/cube.json")" = 422 ] && grep -q "POST /volume measures a scene" "$T/body"'
check "model of a scene: 415" '[ "$(status POST /model -H "Content-Type: model/x-bpt" --data-binary @"${SURFD_DATA:-../shared/data}/scenes/teapot.bpt")" = 415 ]'

# ---- errors ----------------------------------------------------------------------------------
check "model 422 crossing contour" '[ "$(status POST /model -H "$J" --data-binary "{\"slices\":[{\"z\":0,\"points\":[[0,0],[1,1],[1,0],[0,1]]},{\"z\":1,\"points\":[[0,0],[1,0],[0,1]]}]}")" = 422 ] && grep -q "\"pointer\":\"/slices/0/points\"" "$T/body"'
check "model 422 ?caps" '[ "$(status POST "/model?caps=round" -H "$J" --data-binary @"$C/synthetic_bean.json")" = 422 ] && grep -q "\"pointer\":\"?caps\"" "$T/body"'
check "model 415" '[ "$(status POST /model -H "Content-Type: image/png" --data-binary x)" = 415 ] && is_problem 415'
check "model 400" '[ "$(status POST /model -H "$J" --data-binary "{")" = 400 ] && is_problem 400'
check "404 unknown model" '[ "$(status GET /models/0123456789abcdef)" = 404 ] && is_problem 404 && [ "$(status GET /models/0123456789abcdef/mesh)" = 404 ]'
check "404 bad model id" '[ "$(status GET /models/..%2f..%2fetc)" = 404 ] && [ "$(status GET /models/$id/nothing)" = 404 ]'
check "405 on models" '[ "$(status POST /models/$id)" = 405 ] && [ "$(status PUT /models)" = 405 ] && [ "$(status DELETE /models/$id/mesh)" = 405 ] && [ "$(status GET /model)" = 405 ]'
check "DELETE a model" '[ "$(status DELETE /models/$dome)" = 204 ] && [ "$(status GET /models/$dome)" = 404 ] && [ "$(status DELETE /models/$dome)" = 404 ]'
check "daemon up after errors" 'alive'
stop_daemon

# ---- models survive a restart; a model job survives kill -9 ---------------------------------------
start_daemon "$T/m1" --threads 1 || exit 1
check "models survive a restart" '[ "$(status GET /models/$id)" = 200 ] && [ "$(status GET "/models/$id/mesh?tolerance=0.5")" = 200 ]'
status POST "/render?width=1024&height=1024&method=bvh" -H 'Prefer: respond-async' -H "$J" --data-binary @"${SURFD_DATA:-../shared/data}/scenes/teapot.json" >/dev/null
status POST /model -H 'Prefer: respond-async' -H "$J" --data-binary @"$C/eclipse_rectum.json" >/dev/null
queued=$(header X-Job-Id)
kill -9 "$PID"; wait "$PID" 2>/dev/null; PID=""
start_daemon "$T/m1" --threads 2 || exit 1
check "a model job accepted before kill -9 is run after the restart" 'wait_state "$queued" succeeded 60 && [ "$(status GET /models/$queued)" = 200 ] && grep -q "\"name\":\"Rectum\"" "$T/body"'

finish
