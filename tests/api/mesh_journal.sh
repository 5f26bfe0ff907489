#!/bin/sh
# A model's mesh as a base and a journal of changes (issue 45, API.md "Interactive isosurfaces"),
# as a client meets it: edits of a hierarchy model (levels=2) answer with version 2, 3 ...; the
# delta since the version before, applied by id to the client's copy, gives exactly the STL's
# triangles; the delta since any older version the same; since=0 the whole mesh with the same ids;
# the figures of each answer are those of the mesh (triangles, volume); kill -9 right after an
# edit's 200 loses nothing, and after the restart (the hierarchy rebuilt from the stored volume and
# its edits) a new edit's delta still applies to the copy kept before it.
. "$(dirname "$0")/lib.inc"
V="${SURFD_DATA:-../shared/data}/volumes"
CT="$V/ct_head_crop64_int16.raw"
[ -f "$CT" ] || { bad "../shared/data not found"; checks_done; exit 1; }
RAW='Content-Type: application/octet-stream'
start_daemon "$T/d" || exit 1
field() { python3 -c "import json,sys; print(json.load(open(sys.argv[1])).get(sys.argv[2]))" "$T/body" "$1"; }
# client FILE OP ...: the client's copy by id ($T/copy.json): load (a since=0 delta), apply (a delta
# from the copy's version), same STL (exit 0 when the copy holds the STL's triangles), figures
# TRIANGLES VOLUME (the copy's count and volume match)
client() {
    python3 - "$@" <<'PY'
import json, os, struct, sys
op, path = sys.argv[1], os.environ["T"] + "/copy.json"
def read_delta(f):
    d = open(f, "rb").read()
    assert d[:4] == b"SFMD", d[:4]
    frm, to, nr, na = struct.unpack_from("<4I", d, 4)
    assert len(d) == 20 + 4 * nr + 40 * na
    rem = struct.unpack_from("<%dI" % nr, d, 20)
    add = {}
    for k in range(na):
        tid, *c = struct.unpack_from("<I9f", d, 20 + 4 * nr + 40 * k)
        add[tid] = c
    return frm, to, rem, add
if op == "load":
    frm, to, rem, add = read_delta(sys.argv[2])
    assert frm == 0 and not rem
    json.dump({"version": to, "t": {str(k): v for k, v in add.items()}}, open(path, "w"))
elif op == "apply":
    c = json.load(open(path))
    frm, to, rem, add = read_delta(sys.argv[2])
    assert frm == c["version"], (frm, c["version"])
    for r in rem:
        del c["t"][str(r)]          # (a KeyError: an id the copy does not hold)
    for k, v in add.items():
        assert str(k) not in c["t"], k
        c["t"][str(k)] = v
    c["version"] = to
    json.dump(c, open(path, "w"))
elif op == "same":
    c = json.load(open(path))
    s = open(sys.argv[2], "rb").read()
    n = struct.unpack_from("<I", s, 80)[0]
    stl = sorted(tuple(struct.unpack_from("<12f", s, 84 + 50 * k)[3:]) for k in range(n))
    mine = sorted(tuple(v) for v in c["t"].values())
    sys.exit(0 if stl == mine else 1)
elif op == "figures":
    c = json.load(open(path))
    vol = 0.0
    for p in c["t"].values():
        a, b, q = p[0:3], p[3:6], p[6:9]
        vol += (a[0] * (b[1] * q[2] - b[2] * q[1]) + a[1] * (b[2] * q[0] - b[0] * q[2]) + a[2] * (b[0] * q[1] - b[1] * q[0])) / 6
    ok = len(c["t"]) == int(sys.argv[2]) and abs(vol - float(sys.argv[3])) <= 1e-3 * abs(vol) + 1e-3
    sys.exit(0 if ok else 1)
PY
}
export T

code=$(status POST "/isosurface?iso=226.5&levels=2&max_error=0.5&dims=64,64,64&type=int16&spacing=0.9570312,0.9570312,1.5" -H "$RAW" --data-binary @"$CT")
ID=$(field id)
check "a hierarchy model (levels=2): version 1" '[ "$code" = 201 ] && [ "$(field version)" = 1 ]'
status GET "/models/$ID/mesh?format=delta&since=0" >/dev/null; cp "$T/body" "$T/d0"
client load "$T/d0"
status GET "/models/$ID/mesh?format=stl" >/dev/null; cp "$T/body" "$T/v.stl"
check "since=0 loaded by id: the STL's triangles" 'client same "$T/v.stl"'
# edit E: a ball of bone (or air) painted at a place of the skull
edit() {
    python3 tests/tools/edit_tool.py block 10 "$2" -200 3.5 "$T/ball.raw"
    status POST "/models/$ID/edit?region=$1,10,10,10" -H "$RAW" --data-binary @"$T/ball.raw"
}
# follow REGION...: each an edit (bone), then its delta since the version before applied to the
# copy: ok=0 when an edit fails, a delta does not apply or the copy is not the STL; figures=0 when
# an answer's triangles and volume are not the copy's; v the last version
follow() {
    ok=1; figures=1
    for r in "$@"; do
        code=$(edit "$r" 1500); [ "$code" = 200 ] || ok=0
        v=$(field version); TRI=$(field triangles); VOL=$(field volume_mm3)
        code=$(status GET "/models/$ID/mesh?format=delta&since=$((v - 1))"); cp "$T/body" "$T/dv"
        [ "$code" = 200 ] && client apply "$T/dv" || ok=0
        status GET "/models/$ID/mesh?format=stl" >/dev/null; cp "$T/body" "$T/v.stl"
        client same "$T/v.stl" || ok=0
        client figures "$TRI" "$VOL" || figures=0
    done
}
follow 20,24,17 30,8,40 21,25,18 8,40,3
[ "$v" = 5 ] || ok=0
check "four edits: versions 2 .. 5, each delta since the version before applied by id gives the STL's triangles" '[ $ok = 1 ]'
check "... each answer's triangles and volume those of the mesh (moved by what the change did)" '[ $figures = 1 ]'
cp "$T/copy.json" "$T/copy5.json"
code=$(status GET "/models/$ID/mesh?format=delta&since=0"); cp "$T/body" "$T/d0"
client load "$T/d0"
check "since=0 after the edits: the same triangles, by the same ids" '[ "$code" = 200 ] && cmp -s "$T/copy.json" "$T/copy5.json" || python3 -c "
import json,sys; a=json.load(open(sys.argv[1])); b=json.load(open(sys.argv[2])); sys.exit(a != b)" "$T/copy.json" "$T/copy5.json"'
code=$(status GET "/models/$ID/mesh?format=delta&since=2")
check "since=2 (a version the journal holds): 200 from 2 to 5" '[ "$code" = 200 ] && python3 -c "
import struct,sys; d=open(sys.argv[1],\"rb\").read(); sys.exit(struct.unpack_from(\"<2I\", d, 4) != (2, 5))" "$T/body"'
# kill -9 right after a 200: nothing lost
code=$(edit "12,30,30" 1500)
kill -9 "$PID"; wait "$PID" 2>/dev/null; PID=""
start_daemon "$T/d" || exit 1
code2=$(status GET "/models/$ID")
check "kill -9 right after an edit's 200, restarted: the model at version 6" '[ "$code" = 200 ] && [ "$code2" = 200 ] && [ "$(field version)" = 6 ]'
code=$(status GET "/models/$ID/mesh?format=delta&since=5"); cp "$T/body" "$T/dv"
cp "$T/copy5.json" "$T/copy.json"
status GET "/models/$ID/mesh?format=stl" >/dev/null; cp "$T/body" "$T/v.stl"
check "... the delta since 5 applied to the copy kept before it: the STL" '[ "$code" = 200 ] && client apply "$T/dv" && client same "$T/v.stl"'
code=$(edit "40,20,30" -1000)
check "an edit after the restart (the hierarchy rebuilt from the store): version 7" '[ "$code" = 200 ] && [ "$(field version)" = 7 ]'
code=$(status GET "/models/$ID/mesh?format=delta&since=6"); cp "$T/body" "$T/dv"
status GET "/models/$ID/mesh?format=stl" >/dev/null; cp "$T/body" "$T/v.stl"
check "... its delta applies to the copy by the same ids: the STL" '[ "$code" = 200 ] && client apply "$T/dv" && client same "$T/v.stl"'
cp "$T/copy.json" "$T/copy7.json"
# concurrent edits of one model: applied one after another, versions never skipped or repeated
status GET "/models/$ID" >/dev/null; v0=$(field version)
for k in 1 2 3 4 5 6; do
    python3 tests/tools/edit_tool.py block 8 $((1000 + 100 * k)) -300 2.5 "$T/c$k.raw"
    curl -s -o "$T/c$k.json" -X POST -H "$RAW" --data-binary @"$T/c$k.raw" "$URL/models/$ID/edit?region=$((5 * k)),20,20,8,8,8" &
    pids="${pids:-} $!"
done
wait $pids # (not the daemon's)
vs=$(for k in 1 2 3 4 5 6; do python3 -c "import json,sys; print(json.load(open(sys.argv[1]))['version'])" "$T/c$k.json"; done | sort -n | tr '\n' ' ')
want=$(seq $((v0 + 1)) $((v0 + 6)) | tr '\n' ' ')
check "six edits of one model at once: versions $want each once" '[ "$vs" = "$want" ]'
code=$(status GET "/models/$ID/mesh?format=delta&since=$v0"); cp "$T/body" "$T/dv"
client load "$T/d0" 2>/dev/null; cp "$T/copy.json" "$T/keep.json"
status GET "/models/$ID/mesh?format=delta&since=0" >/dev/null; cp "$T/body" "$T/d0"
status GET "/models/$ID/mesh?format=stl" >/dev/null; cp "$T/body" "$T/v.stl"
check "... the delta over the six applied to the copy before them: the STL" '[ "$code" = 200 ] && cp "$T/copy7.json" "$T/copy.json" && client apply "$T/dv" && client same "$T/v.stl"'

# compaction (journal-kept 4: a new base every 2 versions, the changes of the last 4 kept)
stop_daemon; start_daemon "$T/d" --journal-kept 4 || exit 1
status GET "/models/$ID/mesh?format=delta&since=0" >/dev/null; cp "$T/body" "$T/d0"; client load "$T/d0"
ok=1
for r in 20,24,17 30,8,40 21,25,18 8,40,3 12,30,30 40,20,30; do
    code=$(edit "$r" -1000); [ "$code" = 200 ] || ok=0
    v=$(field version)
    code=$(status GET "/models/$ID/mesh?format=delta&since=$((v - 1))"); cp "$T/body" "$T/dv"
    [ "$code" = 200 ] && client apply "$T/dv" || ok=0
done
status GET "/models/$ID/mesh?format=stl" >/dev/null; cp "$T/body" "$T/v.stl"
check "six more edits under journal-kept 4: each delta applies, the copy the STL (version $v)" '[ $ok = 1 ] && client same "$T/v.stl"'
code=$(status GET "/models/$ID/mesh?format=delta&since=$((v - 3))")
check "... since 3 versions back: still kept (200)" '[ "$code" = 200 ]'
code=$(status GET "/models/$ID/mesh?format=delta&since=2")
check "... since=2, compacted away: 410 at ?since" '[ "$code" = 410 ]'
n=$(sqlite3 "$T/d/surfd.db" "SELECT count(*) FROM model_volumes WHERE model='$ID' AND seq<0")
check "... the store keeps at most 5 changes of it ($n)" '[ "$n" -le 5 ] && [ "$n" -ge 3 ]'
code=$(status GET "/models/$ID/mesh?format=delta&since=0"); cp "$T/body" "$T/d0"
cp "$T/copy.json" "$T/mine.json"; client load "$T/d0"
check "... since=0 from the new base: the same triangles by the same ids" '[ "$code" = 200 ] && python3 -c "
import json,sys; a=json.load(open(sys.argv[1])); b=json.load(open(sys.argv[2])); sys.exit(a != b)" "$T/copy.json" "$T/mine.json"'

# levels=1 (marching cubes kept): a model edited first on a node that keeps no extraction
# (edit-memory 0: every edit draws every cell, its mesh numbered 0 .. n-1 again), then on one that
# keeps it: that node finds the stored ids are not its own, stores its first edit whole, and
# journals the next ones; kill -9 right after a 200, then the extraction rebuilt from the store
stop_daemon; start_daemon "$T/d" --edit-memory 0 || exit 1
code=$(status POST "/isosurface?iso=226.5&dims=64,64,64&type=int16&spacing=0.9570312,0.9570312,1.5" -H "$RAW" --data-binary @"$CT")
ID=$(field id)
edit 20,24,17 1500 >/dev/null; code=$(edit 30,8,40 1500); v=$(field version)
whole=$(python3 -c "import json,sys; print(json.load(open(sys.argv[1]))['edit']['whole'])" "$T/body")
code2=$(status GET "/models/$ID/mesh?format=delta&since=2")
check "levels=1 on a node keeping no extraction: every cell drawn again (version 3), no journal (since 2: 410)" '[ "$code" = 200 ] && [ "$v" = 3 ] && [ "$whole" = True ] && [ "$code2" = 410 ]'
stop_daemon; start_daemon "$T/d" || exit 1
code=$(edit 21,25,18 -1000); v=$(field version)
whole=$(python3 -c "import json,sys; print(json.load(open(sys.argv[1]))['edit']['whole'])" "$T/body")
code2=$(status GET "/models/$ID/mesh?format=delta&since=3")
check "... then kept: the cells it reaches drawn again, stored whole once (its ids not the store's: since 3, 410)" '[ "$code" = 200 ] && [ "$v" = 4 ] && [ "$whole" = False ] && [ "$code2" = 410 ]'
status GET "/models/$ID/mesh?format=delta&since=0" >/dev/null; cp "$T/body" "$T/d0"; client load "$T/d0"
follow 8,40,3 12,30,30 40,20,30 22,26,19
check "... four more edits journaled: each delta applied by id gives the STL (version $v), the figures the mesh's" '[ $ok = 1 ] && [ $figures = 1 ] && [ "$v" = 8 ]'
cp "$T/copy.json" "$T/copy8.json"
code=$(edit 10,10,10 1500)
kill -9 "$PID"; wait "$PID" 2>/dev/null; PID=""
start_daemon "$T/d" || exit 1
code=$(edit 35,35,35 -1000); v=$(field version)
code2=$(status GET "/models/$ID/mesh?format=delta&since=8"); cp "$T/body" "$T/dv"
status GET "/models/$ID/mesh?format=stl" >/dev/null; cp "$T/body" "$T/v.stl"
check "... kill -9 right after an edit's 200; an edit after the restart (rebuilt): version 10, the delta since 8 applies" '[ "$code" = 200 ] && [ "$v" = 10 ] && [ "$code2" = 200 ] && client apply "$T/dv" && client same "$T/v.stl"'

# merge=pieces: every edit draws the whole mesh again, which the store keeps as the model's new base
# with a change of its ids only ("SFMW", 4 bytes a triangle, as an iso change's): each delta since
# the version before still applies by id
code=$(status POST "/isosurface?iso=226.5&levels=3&max_error=1&merge=pieces&dims=64,64,64&type=int16&spacing=0.9570312,0.9570312,1.5" -H "$RAW" --data-binary @"$CT")
ID=$(field id)
status GET "/models/$ID/mesh?format=delta&since=0" >/dev/null; cp "$T/body" "$T/d0"; client load "$T/d0"
follow 20,24,17 30,8,40
whole=$(sqlite3 "$T/d/surfd.db" "SELECT count(*) FROM model_volumes WHERE model='$ID' AND seq<0 AND hex(substr(data,1,4))='53464D57'")
check "merge=pieces: two edits, each stored whole (a new base, its change of ids only: $whole), each delta since the version before applied by id gives the STL" '[ $ok = 1 ] && [ $figures = 1 ] && [ "$v" = 3 ] && [ "$whole" -ge 1 ]'

# PostgreSQL: kill -9 right after an edit's 200 loses nothing there either
. tests/tools/pg.inc
stop_daemon
chmod 755 "$T"
if pg_start "$T/pg"; then
    start_daemon "$T/dp" --store "$PG_URI" || exit 1
    code=$(status POST "/isosurface?iso=226.5&levels=2&max_error=0.5&dims=64,64,64&type=int16&spacing=0.9570312,0.9570312,1.5" -H "$RAW" --data-binary @"$CT")
    ID=$(field id)
    status GET "/models/$ID/mesh?format=delta&since=0" >/dev/null; cp "$T/body" "$T/d0"; client load "$T/d0"
    edit 20,24,17 1500 >/dev/null
    code=$(edit 30,8,40 1500)
    kill -9 "$PID"; wait "$PID" 2>/dev/null; PID=""
    start_daemon "$T/dp" --store "$PG_URI" || exit 1
    code2=$(status GET "/models/$ID/mesh?format=delta&since=1"); cp "$T/body" "$T/dv"
    status GET "/models/$ID/mesh?format=stl" >/dev/null; cp "$T/body" "$T/v.stl"
    check "PostgreSQL: kill -9 right after an edit's 200; restarted, the delta since 1 applied: the STL (version 3)" '[ "$code" = 200 ] && [ "$code2" = 200 ] && client apply "$T/dv" && client same "$T/v.stl" && python3 -c "
import json,sys; sys.exit(json.load(open(sys.argv[1]))[\"version\"] != 3)" "$T/copy.json"'
    code=$(edit 8,40,3 -1000)
    code2=$(status GET "/models/$ID/mesh?format=delta&since=3"); cp "$T/body" "$T/dv"
    status GET "/models/$ID/mesh?format=stl" >/dev/null; cp "$T/body" "$T/v.stl"
    check "... an edit after the restart: its delta applies by the same ids" '[ "$code" = 200 ] && [ "$code2" = 200 ] && client apply "$T/dv" && client same "$T/v.stl"'
    stop_daemon
    pg_stop
else
    bad "PostgreSQL would not start"
fi
checks_done
