#!/bin/sh
# POST /models/{id}/iso?value=V (issue 45, API.md): a stored volume's model at a new iso as its
# next version, equal to a fresh POST /isosurface at that iso triangle for triangle, at levels=2
# (its change in the journal: the delta since the version before applies by id), levels=3 with
# merge=pieces (drawn whole, its change in the journal too) and levels=1; back
# to the first iso, the first mesh; an iso change kept across a restart (replayed in order with
# the edits); bad values get a 422 at ?value, a body or an FRep model a clear 4xx.
. "$(dirname "$0")/lib.inc"
V="${SURFD_DATA:-../shared/data}/volumes"
CT="$V/ct_head_crop64_int16.raw"
E=tests/tools/edit_tool.py
[ -f "$CT" ] || { bad "../shared/data not found"; checks_done; exit 1; }
RAW='Content-Type: application/octet-stream'
G="dims=64,64,64&type=int16&spacing=0.9570312,0.9570312,1.5"
start_daemon "$T/d" || exit 1
field() { python3 -c "import json,sys; print(json.load(open(sys.argv[1])).get(sys.argv[2]))" "$T/body" "$1"; }
pointer_is() { grep -q "\"pointer\":\"$1\"" "$T/body"; }
stl() { status GET "/models/$1/mesh?format=stl" >/dev/null; cp "$T/body" "$2"; }
# fresh ISO OPTS OUT: a fresh extraction's STL
fresh() { # (its resource into $T/fresh.json)
    status POST "/isosurface?$G&iso=$1$2" -H "$RAW" --data-binary @"$CT" >/dev/null
    cp "$T/body" "$T/fresh.json"
    stl "$(field id)" "$3"
}
# applies FILE: the delta in $T/body, applied by id to the STL FILE's... (python: the copy of since=0)
delta_ok() { # delta_ok ID FROM: the since=0 delta at FROM ($T/at_from) + the delta FROM -> now == the STL now
    python3 - "$T/at_from" "$T/dnow" "$T/now.stl" <<'PY'
import struct, sys
def rd(f):
    d = open(f, "rb").read(); frm, to, nr, na = struct.unpack_from("<4I", d, 4)
    rem = struct.unpack_from("<%dI" % nr, d, 20)
    add = {}
    for k in range(na):
        tid, *c = struct.unpack_from("<I9f", d, 20 + 4 * nr + 40 * k); add[tid] = tuple(c)
    return frm, to, rem, add
_, v, _, t = rd(sys.argv[1])
frm, to, rem, add = rd(sys.argv[2])
assert frm == v, (frm, v)
for r in rem: del t[r]
for k, c in add.items():
    assert k not in t; t[k] = c
s = open(sys.argv[3], "rb").read(); n = struct.unpack_from("<I", s, 80)[0]
stl = sorted(struct.unpack_from("<12f", s, 84 + 50 * k)[3:] for k in range(n))
sys.exit(0 if sorted(t.values()) == stl else 1)
PY
}

for lv in "&levels=2&max_error=0.5" "" "&levels=3&max_error=1&merge=pieces"; do
    code=$(status POST "/isosurface?$G&iso=226.5$lv" -H "$RAW" --data-binary @"$CT")
    ID=$(field id); stl "$ID" "$T/first.stl"
    status GET "/models/$ID/mesh?format=delta&since=0" >/dev/null; cp "$T/body" "$T/at_from"
    code=$(status POST "/models/$ID/iso?value=500")
    check "[${lv:-levels=1}] POST /models/{id}/iso?value=500: 200, version 2, iso 500" '[ "$code" = 200 ] && [ "$(field version)" = 2 ] && [ "$(field iso)" = 500.0 ]'
    cp "$T/body" "$T/changed.json"
    stl "$ID" "$T/now.stl"; fresh 500 "$lv" "$T/f500.stl"
    check "... its mesh a fresh extraction's at iso 500, triangle for triangle" 'python3 $E same "$T/now.stl" "$T/f500.stl"'
    check "... its answer's triangles and volume the fresh extraction's" 'python3 -c "
import json, sys
a, b = json.load(open(sys.argv[1])), json.load(open(sys.argv[2]))
sys.exit(a[\"triangles\"] != b[\"triangles\"] or abs(a[\"volume_mm3\"] - b[\"volume_mm3\"]) > 1e-9 * b[\"volume_mm3\"])" "$T/changed.json" "$T/fresh.json"'
    for k in $(seq 1 100); do # (a levels=1 model's whole-mesh figures measured once the changes rest, a second after)
        status GET "/models/$ID" >/dev/null; [ "$(field topology_version)" = 2 ] && break; sleep 0.1
    done
    check "... and its whole-mesh figures (topology_version 2): the fresh extraction's" 'python3 -c "
import json, sys
a, b = json.load(open(sys.argv[1])), json.load(open(sys.argv[2]))
keys = (\"vertices\", \"triangles\", \"components\", \"euler_characteristic\", \"boundary_edges\", \"nonmanifold_edges\", \"bounds\")
sys.exit(a[\"topology_version\"] != a[\"version\"] or any(a[k] != b[k] for k in keys) or abs(a[\"volume_mm3\"] - b[\"volume_mm3\"]) > 1e-9 * b[\"volume_mm3\"])" "$T/body" "$T/fresh.json"'
    code=$(status GET "/models/$ID/mesh?format=delta&since=1" -H 'Prefer: respond-async'); cp "$T/body" "$T/dnow"
    check "... the delta since 1 (asked async: answered at once, no job) applied by id: the mesh" \
        '[ "$code" = 200 ] && [ "$(header Content-Type)" = application/vnd.surfd.mesh-delta ] && [ -z "$(header Location)" ] && delta_ok'
    code=$(status POST "/models/$ID/iso?value=226.5"); v=$(field version)
    stl "$ID" "$T/now.stl"
    check "... back to iso 226.5: version 3, the first mesh" '[ "$code" = 200 ] && [ "$v" = 3 ] && python3 $E same "$T/now.stl" "$T/first.stl"'
done
# kept across a restart: an edit, then an iso change, then (rebuilt) another edit: a fresh extraction of it
python3 $E block 10 1500 -200 3.5 "$T/ball.raw"
python3 $E apply "$CT" 64,64,64 20,24,17,10,10,10 "$T/ball.raw" "$T/v1.raw"
python3 $E apply "$T/v1.raw" 64,64,64 30,8,40,10,10,10 "$T/ball.raw" "$T/v2.raw"
for lv in "&levels=2&max_error=0.5" ""; do
    code=$(status POST "/isosurface?$G&iso=226.5$lv" -H "$RAW" --data-binary @"$CT"); ID=$(field id)
    status POST "/models/$ID/edit?region=20,24,17,10,10,10" -H "$RAW" --data-binary @"$T/ball.raw" >/dev/null
    status POST "/models/$ID/iso?value=400" >/dev/null
    status GET "/models/$ID/mesh?format=delta&since=0" >/dev/null; cp "$T/body" "$T/at_from"
    stop_daemon; start_daemon "$T/d" || exit 1
    code=$(status POST "/models/$ID/edit?region=30,8,40,10,10,10" -H "$RAW" --data-binary @"$T/ball.raw")
    check "[${lv:-levels=1}] after a restart an edit of a model whose iso changed: 200, version 4, iso 400" '[ "$code" = 200 ] && [ "$(field version)" = 4 ] && [ "$(field iso)" = 400.0 ]'
    stl "$ID" "$T/now.stl"
    status GET "/models/$ID/mesh?format=delta&since=3" >/dev/null; cp "$T/body" "$T/dnow"
    check "... the delta since 3 (the rebuilt extraction's ids) applied by id: the mesh" 'delta_ok'
    status POST "/isosurface?$G&iso=400$lv" -H "$RAW" --data-binary @"$T/v2.raw" >/dev/null; stl "$(field id)" "$T/f.stl"
    check "... its mesh a fresh extraction of the edited volume at iso 400" 'python3 $E same "$T/now.stl" "$T/f.stl"'
done
code=$(status POST "/models/$ID/iso?value=40000")
check "an iso above every sample: 422 at ?value, naming the samples' range" '[ "$code" = 422 ] && pointer_is "?value" && grep -q "samples run from" "$T/body"'
code=$(status POST "/models/$ID/iso?value=nan")
check "value not a number: 422 at ?value" '[ "$code" = 422 ] && pointer_is "?value"'
code=$(status POST "/models/$ID/iso")
check "no value: 422 at ?value" '[ "$code" = 422 ] && pointer_is "?value"'
code=$(status POST "/models/$ID/iso?value=300" -H "$RAW" --data-binary @"$T/ball.raw")
check "a body: 422 (the new iso is ?value)" '[ "$code" = 422 ]'
status GET "/models/$ID" >/dev/null
check "... none of them changed the model: version 4" '[ "$(field version)" = 4 ]'
code=$(status POST /isosurface -H 'Content-Type: application/json' --data-binary '{"bounds": [[-2, -2, -2], [2, 2, 2]], "cell": 0.25, "frep": {"sphere": {"center": [0, 0, 0], "radius": 1}}}')
FID=$(field id)
code=$(status POST "/models/$FID/iso?value=0.5")
check "an FRep model: 409, its surface changes by its edits" '[ "$code" = 409 ]'
code=$(status POST "/models/0123456789abcdef0123456789abcdef/iso?value=1")
check "an unknown model: 404" '[ "$code" = 404 ]'
checks_done
