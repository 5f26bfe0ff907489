#!/bin/sh
# POST /models/{id}/edit through HTTP (issue 15): a block of new samples changes an isosurface
# model, and its mesh equals, triangle for triangle, what a fresh POST /isosurface of the edited
# volume gives: with the hierarchy (levels 2, levels 3 with features) and with marching cubes
# (levels 1, every cell drawn again; merge=pieces, the whole mesh drawn again), and an FRep model by an object (its tree combined); after a restart (the hierarchy rebuilt from the volume and the
# edits kept in the store); the ETag follows the edits; every kind of bad edit with its status and
# pointer, the daemon up after them. An FRep object's volume primitive reads a model's samples as
# edited.
. "$(dirname "$0")/lib.inc"

V="${SURFD_DATA:-../shared/data}/volumes"
CT="$V/ct_head_crop64_int16.raw"
[ -f "$CT" ] || { bad "../shared/data/volumes not found"; checks_done; exit 1; }
RAW='Content-Type: application/octet-stream'
G="dims=64,64,64&type=int16&spacing=0.9570312,0.9570312,1.5"
E=tests/tools/edit_tool.py
start_daemon "$T/d" --threads 2 || exit 1

field() { python3 -c "import json,sys; print(json.load(open(sys.argv[1])).get(sys.argv[2]))" "$T/body" "$1"; }
edit_field() { python3 -c "import json,sys; print(json.load(open(sys.argv[1]))['edit'][sys.argv[2]])" "$T/body" "$1"; }
python3 $E block 12 1400 -100 4.5 "$T/ball.raw"
python3 $E block 10 -1000 300 3 "$T/hole.raw"
python3 $E block 2 500 500 1 "$T/tiny.raw"

# same_as_fresh ID Q VOLUME: model ID's STL against a fresh extraction of VOLUME with query Q
same_as_fresh() {
    status GET "/models/$1/mesh?format=stl" >/dev/null; cp "$T/body" "$T/edited.stl"
    code=$(status POST "/isosurface?$2" -H "$RAW" --data-binary @"$3")
    fresh=$(field id); fvol=$(field volume_mm3); ftri=$(field triangles)
    status GET "/models/$fresh/mesh?format=stl" >/dev/null; cp "$T/body" "$T/fresh.stl"
    [ "$code" = 201 ] && python3 $E same "$T/edited.stl" "$T/fresh.stl"
}

for opts in "iso=226.5&levels=2&max_error=0.5" "iso=226.5&levels=3&max_error=1&features=sharp" "iso=226.5" \
            "iso=226.5&levels=3&max_error=1&merge=pieces"; do
    Q="$G&$opts"
    code=$(status POST "/isosurface?$Q" -H "$RAW" --data-binary @"$CT")
    id=$(field id)
    check "[$opts] the model, edits 0, its edit link" '[ "$code" = 201 ] && [ "$(field edits)" = 0 ] && grep -q "/models/$id/edit" "$T/body"'
    code=$(status POST "/models/$id/edit?region=20,24,17,12,12,12" -H "$RAW" --data-binary @"$T/ball.raw")
    check "... a 12^3 ball of bone: 200, edits 1, the cells drawn again and the triangles said" '[ "$code" = 200 ] && [ "$(field edits)" = 1 ] && [ "$(edit_field cells_rebuilt)" -gt 0 ] && [ "$(edit_field triangles_added)" -gt 0 ] && [ "$(field boundary_edges)" = 0 ] && [ "$(field nonmanifold_edges)" = 0 ]'
    evol=$(field volume_mm3); etri=$(field triangles); whole=$(edit_field whole)
    case "$opts" in *merge=pieces*) check "... merge=pieces: the whole mesh drawn again (whole)" '[ "$whole" = True ]' ;;
                    *) check "... only the cells it reaches (not every cell)" '[ "$whole" = False ]' ;; esac
    code=$(status POST "/models/$id/edit?region=0,50,52,10,10,10" -H "$RAW" --data-binary @"$T/hole.raw")
    check "... a second edit, on the border: edits 2" '[ "$code" = 200 ] && [ "$(field edits)" = 2 ]'
    evol=$(field volume_mm3); etri=$(field triangles)
    python3 $E apply "$CT" 64,64,64 20,24,17,12,12,12 "$T/ball.raw" "$T/v1.raw"
    python3 $E apply "$T/v1.raw" 64,64,64 0,50,52,10,10,10 "$T/hole.raw" "$T/v2.raw"
    check "... the mesh equals a fresh POST /isosurface of the edited volume, triangle for triangle" 'same_as_fresh "$id" "$Q" "$T/v2.raw"'
    check "... the same triangle count and volume (within rounding: an edit's figures move by what it changed)" '[ "$ftri" = "$etri" ] && python3 -c "import sys; a, b = map(float, sys.argv[1:]); sys.exit(abs(a - b) > 1e-9 * abs(a))" "$fvol" "$evol"'
    status GET "/models/$fresh" >/dev/null; cp "$T/body" "$T/fresh.json"
    for k in $(seq 1 100); do # (the whole mesh measured once the edits rest, a second after the last)
        status GET "/models/$id" >/dev/null
        [ "$(field topology_version)" = 3 ] && break
        sleep 0.1
    done
    check "... once the edits rest, the whole mesh measured (topology_version 3): the fresh extraction's figures" 'python3 -c "
import json, sys
a, b = json.load(open(sys.argv[1])), json.load(open(sys.argv[2]))
keys = (\"vertices\", \"triangles\", \"components\", \"euler_characteristic\", \"boundary_edges\", \"nonmanifold_edges\", \"bounds\")
sys.exit(a[\"topology_version\"] != a[\"version\"] or any(a[k] != b[k] for k in keys) or abs(a[\"volume_mm3\"] - b[\"volume_mm3\"]) > 1e-9 * b[\"volume_mm3\"])" "$T/body" "$T/fresh.json"'
done

# ---- a restart: the hierarchy rebuilt from the stored volume and its edits ---------------------------
Q="$G&iso=226.5&levels=2&max_error=0.5"
code=$(status POST "/isosurface?$Q" -H "$RAW" --data-binary @"$CT"); id=$(field id)
status POST "/models/$id/edit?region=20,24,17,12,12,12" -H "$RAW" --data-binary @"$T/ball.raw" >/dev/null
etag1=$(status GET "/models/$id" >/dev/null; header ETag)
stop_daemon
start_daemon "$T/d" --threads 2 || exit 1
code=$(status POST "/models/$id/edit?region=0,50,52,10,10,10" -H "$RAW" --data-binary @"$T/hole.raw")
check "after a restart: the next edit (edits 2) on the rebuilt hierarchy" '[ "$code" = 200 ] && [ "$(field edits)" = 2 ]'
check "... equal to a fresh extraction of the twice edited volume" 'same_as_fresh "$id" "$Q" "$T/v2.raw"'
for k in $(seq 1 100); do # (the figures measured after the edits rest change the resource, and its tag)
    status GET "/models/$id" >/dev/null; [ "$(field topology_version)" = 3 ] && break; sleep 0.1
done
etag2=$(status GET "/models/$id" >/dev/null; header ETag)
check "the ETag follows the edits (and 304 on the new one)" '[ -n "$etag1" ] && [ "$etag1" != "$etag2" ] && [ "$(status GET "/models/$id" -H "If-None-Match: $etag2")" = 304 ] && [ "$(status GET "/models/$id" -H "If-None-Match: $etag1")" = 200 ]'
check "... and the mesh served is the edited one" '[ "$(status GET "/models/$id/mesh?format=stl")" = 200 ] && cmp -s "$T/body" "$T/edited.stl"'
code=$(status POST "/models/$id/edit?region=0,0,0,2,2,2" -H "$RAW" --data-binary @"$T/tiny.raw" -H 'Prefer: respond-async')
job=$(header Location | sed 's,.*/,,')
check "an edit can be asynchronous: 202 and its job, which succeeds" '[ "$code" = 202 ] && [ -n "$job" ] && wait_state "$job" succeeded'

# ---- an FRep object reads a model's samples as edited (the volume primitive) ----------------------
Q1="dims=64,64,64&type=int16&spacing=1,1,1&iso=226.5"
code=$(status POST "/isosurface?$Q1" -H "$RAW" --data-binary @"$CT"); vid=$(field id); vvol=$(field volume_mm3); vtri=$(field triangles)
VOLREQ="{\"bounds\": [[0, 0, 0], [63, 63, 63]], \"cell\": 1, \"frep\": {\"volume\": {\"model\": \"$vid\"}}}"
code=$(status POST /isosurface -H 'Content-Type: application/json' --data-binary "$VOLREQ")
check "an FRep {volume: model} on the model's own grid: the model's mesh (its volume and triangles)" '[ "$code" = 201 ] && [ "$(field source)" = frep ] && [ "$(field volume_mm3)" = "$vvol" ] && [ "$(field triangles)" = "$vtri" ]'
code=$(status POST "/models/$vid/edit?region=20,24,17,12,12,12" -H "$RAW" --data-binary @"$T/ball.raw"); evol=$(field volume_mm3); etri=$(field triangles)
code=$(status POST /isosurface -H 'Content-Type: application/json' --data-binary "$VOLREQ")
check "... after an edit of the model, the edited samples (its volume within rounding)" '[ "$code" = 201 ] && [ "$evol" != "$vvol" ] && python3 -c "import sys; a, b = map(float, sys.argv[1:]); sys.exit(abs(a - b) > 1e-9 * abs(a))" "$(field volume_mm3)" "$evol" && [ "$(field triangles)" = "$etri" ]'
code=$(status POST /isosurface -H 'Content-Type: application/json' --data-binary "{\"bounds\": [[-1, -1, -1], [64, 64, 64]], \"cell\": 1, \"frep\": {\"union\": [{\"volume\": {\"model\": \"$vid\", \"scale\": 0.01}}, {\"sphere\": {\"center\": [32, 32, 32], \"radius\": 12}}]}}")
check "... in a union with a ball (seed 002's hybrid): closed, and more than the model" '[ "$code" = 201 ] && [ "$(field boundary_edges)" = 0 ] && [ "$(field nonmanifold_edges)" = 0 ] && python3 -c "import sys; sys.exit(0 if float(sys.argv[1]) > float(sys.argv[2]) else 1)" "$(field volume_mm3)" "$evol"'
pointer() { python3 -c "import json,sys; e=json.load(open(sys.argv[1])).get('errors'); print(e[0]['pointer'] if e else '')" "$T/body"; }
code=$(status POST /isosurface -H 'Content-Type: application/json' --data-binary '{"bounds": [[0, 0, 0], [9, 9, 9]], "cell": 1, "frep": {"union": [{"sphere": {"center": [0, 0, 0], "radius": 3}}, {"volume": {"model": "0123456789abcdef0123456789abcdef"}}]}}')
check "an FRep volume of no such model: 422 at its member" '[ "$code" = 422 ] && [ "$(pointer)" = /frep/union/1/volume/model ]'
status POST /model -H 'Content-Type: application/json' --data-binary @"${SURFD_DATA:-../shared/data}/contours/synthetic_bean.json" >/dev/null; bean=$(field id)
code=$(status POST /isosurface -H 'Content-Type: application/json' --data-binary "{\"bounds\": [[0, 0, 0], [9, 9, 9]], \"cell\": 1, \"frep\": {\"volume\": {\"model\": \"$bean\"}}}")
check "... of a contour model: 422 at its member" '[ "$code" = 422 ] && [ "$(pointer)" = /frep/volume/model ]'
printf '%s' "$VOLREQ" >"$T/vol.json"
$S isosurface "$T/vol.json" >/dev/null 2>"$T/err"; rc=$?
check "... offline (surfd isosurface): refused, naming the member" '[ $rc -ne 0 ] && grep -q "/frep/volume/model" "$T/err"'

# ---- an FRep model edited by an object: its tree combined, every cell drawn again -------------------
J='Content-Type: application/json'
BOX='{"box": {"min": [-1, -1, -1], "max": [1, 1, 1]}}'
BALL='{"sphere": {"center": [1, 1, 1], "radius": 0.7}}'
RING='{"torus": {"center": [0, 0, -1], "axis": [0, 0, 1], "major": 0.8, "minor": 0.25}}'
frep_req() { printf '{"bounds": [[-1.6, -1.6, -1.6], [1.6, 1.6, 1.6]], "cell": 0.08, "frep": %s}' "$1"; }
code=$(status POST "/isosurface?levels=2&features=sharp" -H "$J" --data-binary "$(frep_req "$BOX")"); fm=$(field id)
code=$(status POST "/models/$fm/edit" -H "$J" --data-binary "{\"op\": \"subtract\", \"object\": $BALL}")
check "an FRep model: {op: subtract, object}: 200, edits 1, every cell drawn again (whole)" '[ "$code" = 200 ] && [ "$(field edits)" = 1 ] && [ "$(edit_field whole)" = True ] && [ "$(field boundary_edges)" = 0 ]'
code=$(status POST "/models/$fm/edit" -H "$J" --data-binary "{\"op\": \"union\", \"object\": $RING, \"alpha\": 1}")
evol=$(field volume_mm3); etri=$(field triangles)
check "... then {op: union, object, alpha: 1}: edits 2" '[ "$code" = 200 ] && [ "$(field edits)" = 2 ]'
status GET "/models/$fm/mesh?format=stl" >/dev/null; cp "$T/body" "$T/edited.stl"
code=$(status POST "/isosurface?levels=2&features=sharp" -H "$J" --data-binary "$(frep_req "{\"union\": [{\"subtract\": [$BOX, $BALL]}, $RING], \"alpha\": 1}")")
check "... equal to a fresh POST /isosurface of the combined tree (volume, triangles, STL)" '[ "$code" = 201 ] && [ "$(field volume_mm3)" = "$evol" ] && [ "$(field triangles)" = "$etri" ] && status GET "/models/$(field id)/mesh?format=stl" >/dev/null && python3 $E same "$T/edited.stl" "$T/body"'
bad_frep() { # bad_frep LABEL STATUS POINTER BODY
    label=$1; want=$2; ptr=$3
    code=$(status POST "/models/$fm/edit" -H "$J" --data-binary "$4")
    check "bad FRep edit: $label -> $want${ptr:+ at $ptr}" '[ "$code" = "$want" ] && is_problem "$want" && { [ -z "$ptr" ] || [ "$(pointer)" = "$ptr" ]; }'
}
bad_frep "an unknown op" 422 /op "{\"op\": \"xor\", \"object\": $BALL}"
bad_frep "no object" 422 /object '{"op": "union"}'
bad_frep "a bad radius inside the object" 422 /object/sphere/radius '{"op": "union", "object": {"sphere": {"center": [0, 0, 0], "radius": -1}}}'
bad_frep "an unknown member" 422 /colour "{\"op\": \"union\", \"object\": $BALL, \"colour\": 1}"
bad_frep "alpha out of range" 422 /alpha "{\"op\": \"union\", \"object\": $BALL, \"alpha\": 2}"
bad_frep "not JSON" 400 "" '{"op": '
code=$(status POST "/models/$fm/edit?region=0,0,0,2,2,2" -H "$RAW" --data-binary @"$T/tiny.raw")
check "bad edit: raw samples to an FRep model -> 409" '[ "$code" = 409 ] && is_problem 409'
code=$(status POST "/models/$vid/edit" -H "$J" --data-binary "{\"op\": \"union\", \"object\": $BALL}")
check "bad edit: an FRep object to a model of samples -> 409" '[ "$code" = 409 ] && is_problem 409'

# ---- bad edits -----------------------------------------------------------------------------------
bad_edit() { # bad_edit LABEL STATUS POINTER QUERY [curl args]
    label=$1; want=$2; ptr=$3; q=$4; shift 4
    code=$(status POST "/models/$id/edit$q" "$@")
    check "bad edit: $label -> $want${ptr:+ at $ptr}" '[ "$code" = "$want" ] && is_problem "$want" && { [ -z "$ptr" ] || [ "$(pointer)" = "$ptr" ]; }'
}
bad_edit "no region" 422 "?region" "" -H "$RAW" --data-binary @"$T/ball.raw"
bad_edit "a region of five numbers" 422 "?region" "?region=1,2,3,4,5" -H "$RAW" --data-binary @"$T/ball.raw"
bad_edit "a region past the volume" 422 "?region" "?region=60,0,0,12,12,12" -H "$RAW" --data-binary @"$T/ball.raw"
bad_edit "a negative corner" 422 "?region" "?region=-1,0,0,12,12,12" -H "$RAW" --data-binary @"$T/ball.raw"
bad_edit "a fractional size" 422 "?region" "?region=0,0,0,11.5,12,12" -H "$RAW" --data-binary @"$T/ball.raw"
bad_edit "an empty region" 422 "?region" "?region=0,0,0,0,12,12" -H "$RAW" --data-binary ""
bad_edit "a body of the wrong length" 422 "" "?region=0,0,0,12,12,11" -H "$RAW" --data-binary @"$T/ball.raw"
code=$(status POST "/models/0123456789abcdef0123456789abcdef/edit?region=0,0,0,12,12,12" -H "$RAW" --data-binary @"$T/ball.raw")
check "bad edit: no such model -> 404" '[ "$code" = 404 ] && is_problem 404'
check "bad edit: GET on /edit -> 405 with Allow: POST" '[ "$(status GET "/models/$id/edit")" = 405 ] && [ "$(header Allow)" = POST ]'
C="${SURFD_DATA:-../shared/data}/contours"
code=$(status POST /model -H 'Content-Type: application/json' --data-binary @"$C/synthetic_bean.json"); cid=$(field id)
code=$(status POST "/models/$cid/edit?region=0,0,0,12,12,12" -H "$RAW" --data-binary @"$T/ball.raw")
check "bad edit: a contour model -> 409" '[ "$code" = 409 ] && is_problem 409'
check "the daemon is up after them, and the model as it was" 'alive && [ "$(status GET "/models/$id")" = 200 ] && [ "$(field edits)" = 3 ]'
check "deleting the model deletes its volume: an edit then finds no model" '[ "$(status DELETE "/models/$id")" = 204 ] && [ "$(status POST "/models/$id/edit?region=0,0,0,2,2,2" -H "$RAW" --data-binary @"$T/tiny.raw")" = 404 ]'

# ---- the caps: a body over max-body is a 413 before it is read; with edit-memory 0 nothing is kept and
# every edit rebuilds its hierarchy from the store, with the same result ------------------------------
stop_daemon
start_daemon "$T/d" --threads 2 --max-body 2048 --edit-memory 0 || exit 1
Q="$G&iso=226.5&levels=2&max_error=0.5"
code=$(status POST "/isosurface?$Q" -H "$RAW" --data-binary @"$CT"); id=$(field id)
code=$(status POST "/models/$id/edit?region=20,24,17,12,12,12" -H "$RAW" --data-binary @"$T/ball.raw")
check "an edit body over max-body: 413" '[ "$code" = 413 ] && is_problem 413'
code=$(status POST "/models/$id/edit?region=0,50,52,10,10,10" -H "$RAW" --data-binary @"$T/hole.raw")
python3 $E apply "$CT" 64,64,64 0,50,52,10,10,10 "$T/hole.raw" "$T/v3.raw"
check "edit-memory 0: the edit rebuilds the hierarchy from the store, equal to a fresh extraction" '[ "$code" = 200 ] && same_as_fresh "$id" "$Q" "$T/v3.raw"'
python3 -c "import sqlite3, sys; db = sqlite3.connect(sys.argv[1]); db.execute('UPDATE model_volumes SET data=zeroblob(length(data)) WHERE model=?1 AND seq=0', (sys.argv[2],)); db.commit()" "$T/d/surfd.db" "$id"
code=$(status POST "/models/$id/edit?region=0,0,0,2,2,2" -H "$RAW" --data-binary @"$T/tiny.raw")
check "a stored volume damaged on disk: the edit is a 500 problem that says so, the model as it was" '[ "$code" = 500 ] && is_problem 500 && grep -q damaged "$T/body" && [ "$(status GET "/models/$id")" = 200 ] && [ "$(field edits)" = 1 ]'

finish
