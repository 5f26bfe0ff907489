#!/bin/sh
# Matrix models through HTTP (issue 16, seed 003): POST /model with six relief matrices (made here
# by tests/tools/matrix_tool.py, an implementation of Table 1 of its own) gives a closed, manifold
# mesh model with the seed's counts, which meshes, renders and is measured like any model; POST
# /volume measures one without storing it; POST /matrix-model turns a volume back into the same
# matrices (exact, or exact false for a body with a cavity); the offline CLI takes them; every kind
# of bad matrix model is a 422 naming the member or element.
. "$(dirname "$0")/lib.inc"

J='Content-Type: application/json'
RAW='Content-Type: application/octet-stream'
M=tests/tools/matrix_tool.py
start_daemon "$T/d" --threads 2 || exit 1
field() { python3 -c "import json,sys; print(json.load(open(sys.argv[1])).get(sys.argv[2]))" "$T/body" "$1"; }
pointer() { python3 -c "import json,sys; e=json.load(open(sys.argv[1])).get('errors'); print(e[0]['pointer'] if e else '')" "$T/body"; }
near() { python3 -c "import sys; sys.exit(0 if abs(float(sys.argv[1]) / float(sys.argv[2]) - 1) < float(sys.argv[3]) else 1)" "$@"; }

python3 $M ball 36 14 "$T/ball.json"
code=$(status POST /model -H "$J" --data-binary @"$T/ball.json"); id=$(field id)
check "a ball's matrix model: 201, source matrix, Location" '[ "$code" = 201 ] && [ "$(field source)" = matrix ] && [ "$(header Location)" = "/models/$id" ]'
check "... a closed 2-manifold, one component, Euler characteristic 2" '[ "$(field boundary_edges)" = 0 ] && [ "$(field nonmanifold_edges)" = 0 ] && [ "$(field components)" = 1 ] && [ "$(field euler_characteristic)" = 2 ]'
check "... its volume within 3 % of the ball's" 'near "$(field volume_mm3)" "$(python3 -c "print(4 / 3 * 3.141592653589793 * 14 ** 3)")" 0.03'
check "... the seed's counts: surface voxels, base and redundant ones; the fragments': no computed vertex, none dropped" '[ "$(field voxels)" -gt 0 ] && [ "$(field base_voxels)" -gt 0 ] && [ "$(field redundant_voxels)" -gt 0 ] && [ "$(field mesher)" = fragments ] && [ "$(field computed_vertices)" = 0 ] && [ "$(field dropped_voxels)" = 0 ]'
vol=$(field volume_mm3); fvol=$vol; fverts=$(field vertices)
code=$(status GET "/models/$id/mesh?format=stl")
check "... its STL closed, with the model's volume" '[ "$code" = 200 ] && python3 tests/tools/stl_check.py "$T/body" "$vol" >/dev/null'
code=$(status GET "/models/$id/render?width=160&height=120")
check "... it renders" '[ "$code" = 200 ] && [ "$(header Content-Type)" = image/png ]'
python3 $M box 20 3 15 4 12 5 18 "$T/box.json"
code=$(status POST /model -H "$J" --data-binary @"$T/box.json")
check "a box 12 x 8 x 13: closed, its faces and edges kept, its corners cut by tetrahedra: 1248 - 8 / 6" '[ "$code" = 201 ] && [ "$(field boundary_edges)" = 0 ] && [ "$(field components)" = 1 ] && near "$(field volume_mm3)" "$(python3 -c "print(1248 - 8 / 6)")" 1e-9'
python3 $M steps 24 "$T/steps.json"
code=$(status POST /model -H "$J" --data-binary @"$T/steps.json")
check "a stepped pyramid: closed, one component" '[ "$code" = 201 ] && [ "$(field boundary_edges)" = 0 ] && [ "$(field nonmanifold_edges)" = 0 ] && [ "$(field components)" = 1 ]'
python3 -c "
import json, sys
b = json.load(open(sys.argv[1])); b['mesher'] = 'chamfer'; json.dump(b, open(sys.argv[2], 'w'))" "$T/ball.json" "$T/chamfer.json"
code=$(status POST /model -H "$J" --data-binary @"$T/chamfer.json"); chamfer=$(field id); cvol=$(field volume_mm3)
check "\"mesher\": \"chamfer\": closed, within 3 %, its vertices off the corners counted, more of them than the fragments'" '[ "$code" = 201 ] && [ "$(field mesher)" = chamfer ] && [ "$(field boundary_edges)" = 0 ] && [ "$(field nonmanifold_edges)" = 0 ] && near "$cvol" "$(python3 -c "print(4 / 3 * 3.141592653589793 * 14 ** 3)")" 0.03 && [ "$(field computed_vertices)" -gt 0 ] && [ "$(field vertices)" -gt "$fverts" ]'
python3 -c "
import json, sys
b = json.load(open(sys.argv[1])); b['mesher'] = 'marching'; json.dump(b, open(sys.argv[2], 'w'))" "$T/ball.json" "$T/badmesher.json"
code=$(status POST /model -H "$J" --data-binary @"$T/badmesher.json")
check "\"mesher\": \"marching\": 422 at /mesher" '[ "$code" = 422 ] && [ "$(pointer)" = /mesher ]'
python3 $M box 12 5 6 2 10 6 7 "$T/rod.json"
code=$(status POST /model -H "$J" --data-binary @"$T/rod.json")
check "a rod a voxel across, 8 long: kept, closed, but for its end voxels (no volume: dropped): 6" '[ "$code" = 201 ] && [ "$(field boundary_edges)" = 0 ] && [ "$(field dropped_voxels)" = 2 ] && near "$(field volume_mm3)" 6 1e-9'
python3 $M box 12 5 6 5 6 5 6 "$T/lone.json"
code=$(status POST /model -H "$J" --data-binary @"$T/lone.json")
check "a lone voxel: the fragments keep none of it, 422 at /mesher saying so" '[ "$code" = 422 ] && [ "$(pointer)" = /mesher ] && grep -q "chamfer" "$T/body"'
code=$(status POST /volume -H "$J" --data-binary @"$T/ball.json")
check "POST /volume measures a matrix model without storing it" '[ "$code" = 200 ] && [ "$(field source)" = matrix ] && [ "$(field id)" = "" ]'

# ---- a volume back to its matrices --------------------------------------------------------------------
python3 $M mask 36 ball 14 "$T/ball.raw"
code=$(status POST "/matrix-model?iso=128&dims=36,36,36&type=uint8&origin=0.5,0.5,0.5" -H "$RAW" --data-binary @"$T/ball.raw")
same=$(python3 -c "
import json, sys
a = json.load(open(sys.argv[1])); b = json.load(open(sys.argv[2]))
print(all(a['matrix_model'][k] == b['matrix_model'][k] for k in ('M0', 'M1', 'M2', 'M3', 'M4', 'M5')) and a['exact'])" "$T/body" "$T/ball.json")
check "POST /matrix-model of the ball's voxels: the same six matrices, exact" '[ "$code" = 200 ] && [ "$same" = True ] && grep -q "\"bounds\":\[\[0.0,0.0,0.0\],\[36.0,36.0,36.0\]\]" "$T/body"'
cp "$T/body" "$T/back.json"
code=$(status POST /model -H "$J" --data-binary @"$T/back.json")
check "... which POST /model takes back" '[ "$code" = 201 ] && [ "$(field source)" = matrix ]'
python3 - "$T/ball.raw" "$T/hollow.raw" <<'PY'
import sys
d = bytearray(open(sys.argv[1], "rb").read())
for z in range(14, 22):
    for y in range(14, 22):
        for x in range(14, 22):
            d[x + 36 * (y + 36 * z)] = 0
open(sys.argv[2], "wb").write(d)
PY
code=$(status POST "/matrix-model?iso=128&dims=36,36,36&type=uint8" -H "$RAW" --data-binary @"$T/hollow.raw")
check "... of a ball with a cavity: answered, exact false (the seed's limit)" '[ "$code" = 200 ] && [ "$(field exact)" = False ]'
check "... without ?iso: 422 at ?iso" '[ "$(status POST "/matrix-model?dims=36,36,36&type=uint8" -H "$RAW" --data-binary @"$T/ball.raw")" = 422 ] && [ "$(pointer)" = "?iso" ]'

# ---- a stored model's matrices by rays; the orthographic views they are made from -----------------
# (the chamfered mesh: it keeps every voxel centre on its side, so the rays give the voxels back)
ball=$chamfer; vol=$cvol
code=$(status GET "/models/$ball"); size=$(python3 -c "
import json, sys
b = json.load(open(sys.argv[1]))['bounds']; print(','.join(str(round(b[1][k] - b[0][k])) for k in range(3)))" "$T/body")
code=$(status POST "/matrix-model?model=$ball&size=$size")
cp "$T/body" "$T/rays.json"
check "POST /matrix-model?model=ID&size= of the ball's model (its exact tracer's rays on the voxels' own grid): exact" '[ "$code" = 200 ] && [ "$(field exact)" = True ]'
code=$(status POST /model -H "$J" --data-binary @"$T/rays.json")
check "... the same voxels: posted back, the same volume (the fragments' of the ball's matrices)" '[ "$code" = 201 ] && near "$(field volume_mm3)" "$fvol" 1e-9'
for k in 0 1 2 3 4 5; do
    view=$(echo "+x +y +z -x -y -z" | cut -d' ' -f$((k + 1)))
    wh=$(python3 -c "
import json, sys
mm = json.load(open(sys.argv[1]))['matrix_model']; m = mm['M' + sys.argv[2]]; b = mm['bounds']
print('width=%d&height=%d&view_height=%g' % (len(m[0]), len(m), b[1][1 if sys.argv[2] in '25' else 2] - b[0][1 if sys.argv[2] in '25' else 2]))" "$T/rays.json" $k)
    v=$(printf '%s' "$view" | sed 's/+/%2B/')
    code=$(status POST "/render?projection=orthographic&view=$v&$wh" -H "$J" --data-binary "{\"image\": {\"background\": [1, 0, 1]}, \"objects\": [{\"type\": \"model\", \"id\": \"$ball\"}]}")
    check "the ball's orthographic view $view (a pixel a voxel line) is matrix M$k's silhouette, pixel for pixel" '[ "$code" = 200 ] && [ "$(python3 $M silhouette "$T/rays.json" $k "$T/body")" = 0 ]'
done
code=$(status GET "/models/$ball/render?projection=orthographic&view=-z&width=64&height=48")
check "GET /models/{id}/render?projection=orthographic&view=-z: the view framed" '[ "$code" = 200 ] && python3 -c "import sys; sys.exit(0 if 0.2 < float(sys.argv[1]) < 0.8 else 1)" "$(python3 tests/tools/png_cover.py "$T/body")"'
code=$(status POST "/isosurface?iso=128&dims=36,36,36&type=uint8" -H "$RAW" --data-binary @"$T/ball.raw"); iso=$(field id); isovol=$(field volume_mm3)
code=$(status POST "/matrix-model?model=$iso")
cp "$T/body" "$T/isorays.json"
check "... of an isosurface model (a mesh: Embree's rays), the default size: 128 along the longest side, exact" '[ "$code" = 200 ] && [ "$(field exact)" = True ] && grep -q "\"size\":\[128,128,128\]" "$T/body"'
code=$(status POST /volume -H "$J" --data-binary @"$T/isorays.json")
check "... its matrix model's volume within 1 % of the isosurface's" '[ "$code" = 200 ] && near "$(field volume_mm3)" "$isovol" 0.01'
C="${SURFD_DATA:-../shared/data}/contours/eclipse_femoral_head_lt.json"
if [ -f "$C" ]; then
    code=$(status POST /model -H "$J" --data-binary @"$C"); head=$(field id); headvol=$(field volume_mm3)
    code=$(status POST "/matrix-model?model=$head&size=96,92,88")
    cp "$T/body" "$T/headrays.json"
    check "... of a contour model (the patches' exact tracer): answered, exact" '[ "$code" = 200 ] && [ "$(field exact)" = True ]'
    code=$(status POST /volume -H "$J" --data-binary @"$T/headrays.json")
    check "... its matrix model's volume within 1.5 % of the contour model's, one closed component" '[ "$code" = 200 ] && near "$(field volume_mm3)" "$headvol" 0.015 && [ "$(field components)" = 1 ] && [ "$(field boundary_edges)" = 0 ]'
else
    bad "../shared/data/contours not found"
fi
check "?model of no model: 422 at ?model" '[ "$(status POST "/matrix-model?model=0123456789abcdef0123456789abcdef")" = 422 ] && [ "$(pointer)" = "?model" ]'
check "?size not three sides: 422 at ?size" '[ "$(status POST "/matrix-model?model=$ball&size=4,4")" = 422 ] && [ "$(pointer)" = "?size" ]'
check "?size over the cap: 422 at ?size" '[ "$(status POST "/matrix-model?model=$ball&size=4096,4096,4096")" = 422 ] && [ "$(pointer)" = "?size" ]'
check "?model with a body: 422" '[ "$(status POST "/matrix-model?model=$ball" -H "$RAW" --data-binary @"$T/ball.raw")" = 422 ]'
check "?projection=fisheye: 422 at ?projection" '[ "$(status GET "/models/$ball/render?projection=fisheye")" = 422 ] && [ "$(pointer)" = "?projection" ]'
check "?view=+w: 422 at ?view" '[ "$(status GET "/models/$ball/render?view=%2Bw")" = 422 ] && [ "$(pointer)" = "?view" ]'
check "?eye without ?target: 422 at ?target" '[ "$(status GET "/models/$ball/render?eye=1,2,3")" = 422 ] && [ "$(pointer)" = "?target" ]'
check "?eye=1,2: 422 at ?eye" '[ "$(status GET "/models/$ball/render?eye=1,2&target=0,0,0")" = 422 ] && [ "$(pointer)" = "?eye" ]'
code=$(status GET "/models/$ball/render?eye=60,-60,50&target=18,18,18&up=0,0,1&fov=30&width=64&height=48")
check "?eye&target&up&fov: a camera in the query" '[ "$code" = 200 ] && [ "$(header Content-Type)" = image/png ]'

# ---- offline --------------------------------------------------------------------------------------------
$S model "$T/ball.json" --mesh "$T/off.stl" >"$T/out" 2>"$T/err"
check "surfd model MATRIX.json: the resource, and --mesh writes the closed mesh" '[ $? -eq 0 ] && grep -q "\"source\":\"matrix\"" "$T/out" && python3 tests/tools/stl_check.py "$T/off.stl" "$(python3 -c "import json,sys; print(json.load(open(sys.argv[1]))[\"volume_mm3\"])" "$T/out")" >/dev/null'

$S matrix "$T/ball.raw" --iso 128 --dims 36,36,36 --type uint8 --origin 0.5,0.5,0.5 -o "$T/cli.json" 2>"$T/err"
check "surfd matrix VOLUME --iso: the same matrices as POST /matrix-model" '[ $? -eq 0 ] && python3 -c "
import json, sys
a = json.load(open(sys.argv[1])); b = json.load(open(sys.argv[2]))
sys.exit(0 if a[\"matrix_model\"] == b[\"matrix_model\"] and a[\"exact\"] else 1)" "$T/cli.json" "$T/back.json"'
$S matrix "$T/ball.raw" --dims 36,36,36 --type uint8 >/dev/null 2>"$T/err"; rc=$?
check "... without --iso: refused, naming ?iso" '[ $rc -ne 0 ] && grep -q "?iso" "$T/err"'

# ---- bad matrix models -------------------------------------------------------------------------------
edit_json() { python3 -c "
import json, sys
m = json.load(open(sys.argv[1])); exec(sys.argv[2]); json.dump(m, open(sys.argv[3], 'w'))" "$T/ball.json" "$1" "$T/bad.json"; }
bad_matrix() { # bad_matrix LABEL STATUS POINTER PYTHON
    label=$1; want=$2; ptr=$3
    edit_json "$4"
    code=$(status POST /model -H "$J" --data-binary @"$T/bad.json")
    check "bad matrix model: $label -> $want at $ptr" '[ "$code" = "$want" ] && is_problem "$want" && [ "$(pointer)" = "$ptr" ]'
}
bad_matrix "M2 of the wrong shape" 422 /matrix_model/M2 "m['matrix_model']['M2'] = m['matrix_model']['M2'][:-1]"
bad_matrix "a short row" 422 /matrix_model/M4/3 "m['matrix_model']['M4'][3] = m['matrix_model']['M4'][3][:-2]"
bad_matrix "an element past its line" 422 /matrix_model/M0/7/12 "m['matrix_model']['M0'][7][12] = 37"
bad_matrix "a negative element" 422 /matrix_model/M5/0/0 "m['matrix_model']['M5'][0][0] = -1"
bad_matrix "a fractional element" 422 /matrix_model/M1/2/3 "m['matrix_model']['M1'][2][3] = 1.5"
bad_matrix "matrices that contradict each other (a line's first voxel from Xmin past the first from Xmax)" 422 /matrix_model/M3/17/17 "m['matrix_model']['M3'][17][17] = 33"
bad_matrix "a size of 0" 422 /matrix_model/size/1 "m['matrix_model']['size'][1] = 0"
bad_matrix "a size over the cap" 422 /matrix_model/size "m['matrix_model']['size'] = [4096, 4096, 4096]"
bad_matrix "bounds upside down" 422 /matrix_model/bounds/1/2 "m['matrix_model']['bounds'][1][2] = -1"
bad_matrix "an unknown matrix" 422 /matrix_model/M6 "m['matrix_model']['M6'] = []"
bad_matrix "an unknown member" 422 /colour "m['colour'] = 1"
bad_matrix "a line one end sees and the other misses" 422 /matrix_model/M5/0/35 "m['matrix_model']['M2'][0][0] = 18"
bad_matrix "an element naming a voxel the other matrices exclude" 422 /matrix_model/M4/17/18 "m['matrix_model']['M4'][17][18] = 2"
code=$(status POST /model -H "$J" --data-binary '{"matrix_model": {"size": [2, 2')
check "bad matrix model: not JSON -> 400" '[ "$code" = 400 ] && is_problem 400'
check "the daemon is up after them" 'alive'

finish
