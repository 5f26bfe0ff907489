#!/bin/sh
# The front door (issue 19) apart from the page itself (tests/web/page.sh): CORS off by default and
# on for the configured origins; 405 with Allow, 501's title; /metrics through promtool; every
# --help of surfd and surfctl; surfctl for every route (model, volume, mesh, models, view, matrix,
# delete), its plain progress lines with an ETA, and a cancelled job's problem.
. "$(dirname "$0")/lib.inc"
C=./build/surfctl
CT="${SURFD_DATA:-../shared/data}/contours"
[ -f "$CT/synthetic_ellipsoid.json" ] || { bad "../shared/data/contours not found"; finish; }

# ---- CORS -----------------------------------------------------------------------------------
start_daemon "$T/d0" || exit 1
code=$(status OPTIONS /models -H "Origin: https://portal.example" -H "Access-Control-Request-Method: GET")
check "CORS off by default: a preflight is a 405 with Allow, no Access-Control header" '[ "$code" = 405 ] && [ -n "$(header Allow)" ] && ! grep -qi "^Access-Control" "$T/hdr"'
code=$(status GET /models -H "Origin: https://portal.example")
check "... and a GET from a page carries none" '[ "$code" = 200 ] && ! grep -qi "^Access-Control-Allow-Origin" "$T/hdr"'
code=$(status DELETE /render)
check "405 carries Allow" '[ "$code" = 405 ] && [ "$(header Allow)" = POST ]'
code=$(curl -s -o "$T/body" -w '%{http_code}' -X POST -H "Transfer-Encoding: gzip" -H "Content-Type: application/json" --data-binary '{}' "$URL/volume")
check "501's title is Not Implemented" '[ "$code" = 501 ] && grep -q "\"title\":\"Not Implemented\"" "$T/body"'
if command -v promtool >/dev/null; then
    curl -s "$URL/metrics" >"$T/metrics"
    check "/metrics passes promtool check metrics" 'promtool check metrics <"$T/metrics" >"$T/prom" 2>&1'
    [ -s "$T/prom" ] && cat "$T/prom"
else
    bad "no promtool (deploy/install-deps.sh installs prometheus)"
fi
stop_daemon
start_daemon "$T/d1" --cors-origin https://portal.example --cors-origin https://planning.example || exit 1
code=$(status OPTIONS /models/0123456789abcdef0123456789abcdef -H "Origin: https://planning.example" -H "Access-Control-Request-Method: DELETE" -H "Access-Control-Request-Headers: authorization")
check "--cors-origin (twice): a preflight from the second is a 204 naming the origin, methods and headers" '[ "$code" = 204 ] && [ "$(header Access-Control-Allow-Origin)" = https://planning.example ] && header Access-Control-Allow-Methods | grep -q DELETE && header Access-Control-Allow-Headers | grep -qi authorization'
code=$(status GET /models -H "Origin: https://portal.example")
check "... a GET from the first carries Allow-Origin, Vary and the exposed headers" '[ "$code" = 200 ] && [ "$(header Access-Control-Allow-Origin)" = https://portal.example ] && [ "$(header Vary)" = Origin ] && header Access-Control-Expose-Headers | grep -q X-Job-Id'
code=$(status OPTIONS /models -H "Origin: https://evil.example" -H "Access-Control-Request-Method: GET")
check "... a preflight from another origin: 403, no Allow-Origin" '[ "$code" = 403 ] && is_problem 403 && ! grep -qi "^Access-Control-Allow-Origin" "$T/hdr"'
code=$(status GET /models -H "Origin: https://evil.example")
check "... a GET from another origin carries none" '[ "$code" = 200 ] && ! grep -qi "^Access-Control-Allow-Origin" "$T/hdr"'
stop_daemon
$S serve --cors-origin "a.example,b.example" >/dev/null 2>"$T/err"; rc=$?
check "--cors-origin with a comma: refused at start, saying so" '[ $rc -ne 0 ] && grep -q "cors-origin" "$T/err"'

# ---- --help ---------------------------------------------------------------------------------
helps=0
for c in "" serve render model volume isosurface matrix; do
    $S $c --help >"$T/out" 2>"$T/err" && [ -s "$T/out" ] && [ ! -s "$T/err" ] || { helps=1; echo "surfd $c --help"; }
done
check "surfd --help and surfd serve|render|model|volume|isosurface|matrix --help: usage on stdout, exit 0" '[ $helps = 0 ]'
helps=0
for c in "" render model volume isosurface edit matrix models mesh view delete jobs job wait result cancel; do
    $C $c --help >"$T/out" 2>"$T/err" && grep -q "surfctl" "$T/out" || { helps=1; echo "surfctl $c --help"; }
done
check "surfctl --help and --help on every command: usage on stdout, exit 0" '[ $helps = 0 ]'

# ---- surfctl for every route ----------------------------------------------------------------
start_daemon "$T/d2" --sync-wait 5 || exit 1
export SURFD_URL="$URL"
$C --progress=plain model "$CT/synthetic_ellipsoid.json" --caps dome -o "$T/e.vtp" >"$T/out" 2>"$T/err"
id=$(python3 -c "import json,sys; print(json.load(open(sys.argv[1]))['id'])" "$T/out" 2>/dev/null)
check "surfctl model --caps dome -o OUT.vtp: the resource on stdout, the VTK file" '[ -n "$id" ] && grep -q "\"caps\":\"dome\"" "$T/out" && head -c 200 "$T/e.vtp" | grep -q VTKFile'
check "... --progress=plain: a line per step, the last 100 % succeeded" 'grep -q "^surfctl: job [0-9a-f]* 100% succeeded" "$T/err" && ! grep -q "\[#" "$T/err"'
vol=$(python3 -c "import json,sys; print(json.load(open(sys.argv[1]))['volume_mm3'])" "$T/out")
$C volume "$CT/synthetic_ellipsoid.json" --caps dome >"$T/out" 2>/dev/null
check "surfctl volume: the same volume, nothing stored" '[ $? -eq 0 ] && grep -q "\"volume_mm3\":$vol" "$T/out" && ! grep -q "\"id\"" "$T/out"'
$C mesh "$id" -o "$T/e.stl" --tolerance 0.01 2>/dev/null
check "surfctl mesh ID -o OUT.stl --tolerance: closed, the model's volume" '[ $? -eq 0 ] && python3 tests/tools/stl_check.py "$T/e.stl" "$vol" >/dev/null'
$C mesh "$id" -o "$T/e.mesh" --format ply 2>/dev/null
check "surfctl mesh --format ply" '[ $? -eq 0 ] && head -c 3 "$T/e.mesh" | grep -q ply'
check "surfctl models lists it, surfctl models ID shows it" '$C models | grep -q "$id" && $C models "$id" | grep -q "\"volume_mm3\":$vol"'
$C view "$id" -o "$T/v.png" --width 96 --height 72 --projection orthographic --view +z 2>/dev/null
check "surfctl view ID --projection orthographic --view +z (the + escaped)" '[ $? -eq 0 ] && [ "$(head -c 4 "$T/v.png" | od -An -tx1 | tr -d " \n")" = 89504e47 ]'
$C matrix --model "$id" --size 40,25,30 -o "$T/m.json" 2>/dev/null
check "surfctl matrix --model ID --size: the six matrices" '[ $? -eq 0 ] && grep -q "\"size\":\[40,25,30\]" "$T/m.json"'
$C matrix --model 0123456789abcdef0123456789abcdef -o "$T/m.json" 2>"$T/err"; rc=$?
check "... of no model: exit 4 naming ?model" '[ $rc -eq 4 ] && grep -q "?model" "$T/err"'
$C delete "$id" 2>/dev/null
check "surfctl delete ID, then models ID is a 4" '[ $? -eq 0 ] && ! $C models "$id" 2>/dev/null'
$C delete "$id" 2>/dev/null; rc=$?
check "surfctl delete of a deleted model exits 4" '[ $rc -eq 4 ]'
job=$($C render "$D/teapot.json" --async --width 3000 --height 3000 --method montecarlo 2>/dev/null)
$C cancel "$job" >/dev/null 2>&1
$C --progress=none wait "$job" 2>"$T/err"; rc=$?
check "a cancelled job: surfctl wait exits 1 and says so" '[ $rc -eq 1 ] && grep -q "job $job cancelled" "$T/err"'
$C model 2>"$T/err"; rc=$?
check "surfctl model without a file: its usage, exit 2" '[ $rc -eq 2 ] && grep -q "surfctl model CONTOURS" "$T/err"'
finish
