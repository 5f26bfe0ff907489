#!/bin/sh
# Issue 48's finding 10c: a value longer than SQLite holds in one (1e9 bytes: a mesh of 40 M
# triangles, a CT kept for edits, a large result) is kept as pieces. Here store-piece is 64 KB, so
# a small model's mesh and volume, a cached STL and a rendered picture are all kept in pieces:
# made, read back byte for byte (after a restart too), edited, checked by `surfd store check`
# (damage in a piece found), and their pieces gone when the model is deleted; the same on
# PostgreSQL (1 GB at most in one bytea), whose results were chunked already.
. "$(dirname "$0")/lib.inc"
. tests/tools/pg.inc
trap 'stop_daemon; pg_stop; rm -rf "$T"' EXIT

RAW='Content-Type: application/octet-stream'
DB="$T/d/surfd.db"
field() { python3 -c "import json,sys; print(json.load(open(sys.argv[1])).get(sys.argv[2], ''))" "$T/body" "$1"; }
q() { sqlite3 "$DB" "$1"; }
python3 -c "
import struct, sys
n = 48
v = [200 if (x-24)**2 + (y-24)**2 + (z-24)**2 < 400 else 0 for z in range(n) for y in range(n) for x in range(n)]
sys.stdout.buffer.write(struct.pack('<%dh' % len(v), *v))" >"$T/ball.raw"
python3 -c "import struct, sys; sys.stdout.buffer.write(struct.pack('<512h', *([0] * 512)))" >"$T/hole.raw"

start_daemon "$T/d" --store-piece 65536 || exit 1
code=$(status POST "/isosurface?dims=48,48,48&type=int16&iso=100" -H "$RAW" --data-binary @"$T/ball.raw")
mdl=$(field id); tris=$(field triangles); vol=$(field volume_mm3)
check "a ball of $tris triangles from a 221 KB volume: 201" '[ "$code" = 201 ] && [ "$tris" -gt 5000 ]'
check "... its mesh and its volume kept as pieces of 64 KB (4 for the volume)" \
    '[ "$(q "SELECT typeof(source) FROM models WHERE id='\''$mdl'\''")" = text ] && [ "$(q "SELECT count(*) FROM pieces WHERE name = (SELECT data FROM model_volumes WHERE model='\''$mdl'\'')")" = 4 ]'
status GET "/models/$mdl/mesh?format=stl" >/dev/null; cp "$T/body" "$T/a.stl"
check "its STL: binary, $tris triangles, closed" '[ "$(wc -c <"$T/a.stl")" = $((84 + 50 * tris)) ] && python3 tests/tools/stl_check.py "$T/a.stl" "$vol" >/dev/null'
check "... and cached as pieces too" '[ "$(q "SELECT typeof(data) FROM meshes WHERE model='\''$mdl'\''" | sort -u)" = text ]'
code=$(status GET "/models/$mdl/render?width=900&height=900")
cp "$T/body" "$T/a.png"
job=$(q "SELECT id FROM jobs WHERE kind='render' ORDER BY created DESC LIMIT 1")
check "a render of it: 200, a PNG over 64 KB, the job's result kept as pieces" \
    '[ "$code" = 200 ] && [ "$(head -c 4 "$T/a.png" | tail -c 3)" = PNG ] && [ "$(wc -c <"$T/a.png")" -gt 65536 ] && [ "$(q "SELECT typeof(result) FROM jobs WHERE id='\''$job'\''")" = text ]'
check "... read back from its pieces byte for byte" '[ "$(status GET "/jobs/$job/result")" = 200 ] && cmp -s "$T/body" "$T/a.png"'

stop_daemon
start_daemon "$T/d" --store-piece 65536 || exit 1
check "after a restart: the model's STL the same bytes" '[ "$(status GET "/models/$mdl/mesh?format=stl")" = 200 ] && cmp -s "$T/body" "$T/a.stl"'
code=$(status POST "/models/$mdl/edit?region=20,20,20,8,8,8" -H "$RAW" --data-binary @"$T/hole.raw")
check "an edit (its volume read from its pieces): 200, edits 1, a hole in the ball" '[ "$code" = 200 ] && [ "$(field edits)" = 1 ] && [ "$(field volume_mm3)" != "$vol" ]'
evol=$(field volume_mm3)
status GET "/models/$mdl/mesh?format=stl" >/dev/null; cp "$T/body" "$T/e.stl"
check "... its new mesh (pieces again) closed, with the edited volume" 'python3 tests/tools/stl_check.py "$T/e.stl" "$evol" >/dev/null'
stop_daemon

$S store check --data-dir "$T/d" >"$T/out" 2>&1; rc=$?
check "store check over the pieces: sound" '[ "$rc" = 0 ] && grep -q "is sound" "$T/out"'
cp "$DB" "$T/clean.db"
q "UPDATE pieces SET data = zeroblob(length(data)) WHERE rowid = (SELECT min(rowid) FROM pieces WHERE name = (SELECT source FROM models WHERE id='$mdl'))"
$S store check --data-dir "$T/d" >"$T/out" 2>&1; rc=$?
check "a piece of the mesh zeroed: store check exit 1, naming the model" '[ "$rc" = 1 ] && grep -q "model $mdl: its bytes do not match" "$T/out"'
q "DELETE FROM pieces WHERE rowid = (SELECT max(rowid) FROM pieces WHERE name = (SELECT data FROM model_volumes WHERE model='$mdl' AND seq=0))"
$S store check --data-dir "$T/d" >"$T/out" 2>&1
check "a piece of the volume gone: named too" 'grep -q "model volume $mdl/0: its bytes do not match" "$T/out"'
cp "$T/clean.db" "$DB"; rm -f "$DB-wal" "$DB-shm"

start_daemon "$T/d" --store-piece 65536 || exit 1
names="SELECT source FROM models UNION ALL SELECT data FROM model_volumes UNION ALL SELECT data FROM meshes"
before=$(q "SELECT count(*) FROM pieces WHERE name IN ($names)")
check "the model deleted: 204" '[ "$(status DELETE "/models/$mdl")" = 204 ]'
check "... and its $before pieces with it; the render's stay" '[ "$before" -gt 8 ] && [ "$(q "SELECT count(*) FROM pieces WHERE name IN ($names)")" = 0 ] && [ "$(q "SELECT count(*) FROM pieces")" -gt 0 ] && [ "$(status GET "/jobs/$job/result")" = 200 ] && cmp -s "$T/body" "$T/a.png"'
check "... and no piece is left that no row names (the edit's old mesh and meshes went with their rows)" \
    '[ "$(q "SELECT count(*) FROM pieces WHERE name NOT IN (SELECT result FROM jobs WHERE typeof(result)='\''text'\'' UNION SELECT request FROM jobs WHERE typeof(request)='\''text'\'')")" = 0 ]'
stop_daemon

# ---- PostgreSQL ---------------------------------------------------------------------------------
chmod 755 "$T" # the cluster's owner (nobody, under root) reaches its directory inside
pg_start "$T/pg" || { bad "PostgreSQL would not start"; checks_done; exit 1; }
start_daemon "$T/p" --store "$PG_URI" --store-piece 65536 || exit 1
code=$(status POST "/isosurface?dims=48,48,48&type=int16&iso=100" -H "$RAW" --data-binary @"$T/ball.raw")
mdl=$(field id)
check "PostgreSQL: the ball: 201, its mesh and volume as pieces (4 for the volume)" \
    '[ "$code" = 201 ] && [ -n "$(pg_sql "SELECT source_pieces FROM models WHERE id='\''$mdl'\''")" ] && [ "$(pg_sql "SELECT count(*) FROM pieces WHERE name = (SELECT data_pieces FROM model_volumes WHERE model='\''$mdl'\'')")" = 4 ]'
check "... its STL the same bytes as from SQLite, cached as pieces" \
    '[ "$(status GET "/models/$mdl/mesh?format=stl")" = 200 ] && cmp -s "$T/body" "$T/a.stl" && [ "$(pg_sql "SELECT count(*) FROM meshes WHERE model='\''$mdl'\'' AND data_pieces IS NOT NULL")" -ge 1 ]'
stop_daemon
start_daemon "$T/p" --store "$PG_URI" --store-piece 65536 || exit 1
code=$(status POST "/models/$mdl/edit?region=20,20,20,8,8,8" -H "$RAW" --data-binary @"$T/hole.raw")
check "... after a restart, the same edit: 200, the same volume as on SQLite" '[ "$code" = 200 ] && [ "$(field volume_mm3)" = "$evol" ]'
check "... its new mesh the same bytes" '[ "$(status GET "/models/$mdl/mesh?format=stl")" = 200 ] && cmp -s "$T/body" "$T/e.stl"'
check "the model deleted: 204, and every piece with it" '[ "$(status DELETE "/models/$mdl")" = 204 ] && [ "$(pg_sql "SELECT count(*) FROM pieces")" = 0 ]'

finish
