#!/bin/sh
# Values of 1 MB or more are files of the data dir's values/ (daemon/store_sqlite.c, "values kept
# as files"): an iso change of the CT head stored its 27 MB mesh in 320 ms as SQLite pages and in
# tens of ms as a file. Here a ball's model (its mesh and volume over 1 MB), its cached STL and its
# STL job's result are made, each a file of the service user's alone named by its row; an iso
# change replaces the mesh's file and the old one goes; a restart serves the same bytes; `surfd
# store check` finds a file altered or gone; a stray file no row names is swept at start once
# older than a minute (a younger one may be another process's, between its write and its row);
# a model deleted takes its files with it, and every file is always some row's.
. "$(dirname "$0")/lib.inc"

RAW='Content-Type: application/octet-stream'
DB="$T/d/surfd.db"
V="$T/d/values"
field() { python3 -c "import json,sys; print(json.load(open(sys.argv[1])).get(sys.argv[2], ''))" "$T/body" "$1"; }
q() { sqlite3 "$DB" "$1"; }
# the files the rows name, and the files there, each sorted: the same list when no file is astray
named() {
    q "SELECT substr(n, 6, 32) FROM (SELECT source AS n FROM models UNION ALL SELECT data FROM model_volumes
       UNION ALL SELECT data FROM meshes UNION ALL SELECT result FROM jobs UNION ALL SELECT request FROM jobs)
       WHERE typeof(n) = 'text' AND n GLOB 'file:*' ORDER BY 1"
}
present() { ls "$V" | sort; }
file_of() { q "$1" | cut -c6-37; }
python3 -c "
import struct, sys
n = 96
v = [300 if (x-48)**2 + (y-48)**2 + (z-48)**2 < 1600 else 0 for z in range(n) for y in range(n) for x in range(n)]
sys.stdout.buffer.write(struct.pack('<%dh' % len(v), *v))" >"$T/ball.raw"

start_daemon "$T/d" || exit 1
code=$(status POST "/isosurface?dims=96,96,96&type=int16&iso=100" -H "$RAW" --data-binary @"$T/ball.raw")
mdl=$(field id); tris=$(field triangles)
src=$(file_of "SELECT source FROM models WHERE id='$mdl'"); vol=$(file_of "SELECT data FROM model_volumes WHERE model='$mdl' AND seq=0")
check "a ball of $tris triangles from a 1.8 MB volume: 201, its mesh and its volume each a file of values/" \
    '[ "$code" = 201 ] && [ -f "$V/$src" ] && [ -f "$V/$vol" ] && [ "$(wc -c <"$V/$vol")" = $((2 * 96 * 96 * 96)) ]'
check "... values/ 0700, its files 0600" '[ "$(stat -c %a "$V")" = 700 ] && [ "$(stat -c %a "$V/$src")" = 600 ] && [ "$(stat -c %a "$V/$vol")" = 600 ]'
check "... the length its row names, the file's" \
    '[ "$(q "SELECT substr(source, 39) FROM models WHERE id='\''$mdl'\''")" = "$(wc -c <"$V/$src")" ]'
status GET "/models/$mdl/mesh?format=stl" >/dev/null; cp "$T/body" "$T/a.stl"
job=$(q "SELECT id FROM jobs WHERE kind='mesh' AND options LIKE '%format=stl%'")
check "its STL ($tris triangles, closed), cached as a file, the job's result a file" \
    '[ "$(wc -c <"$T/a.stl")" = $((84 + 50 * tris)) ] && python3 tests/tools/stl_check.py "$T/a.stl" - >/dev/null && [ "$(q "SELECT data GLOB '\''file:*'\'' FROM meshes WHERE model='\''$mdl'\''")" = 1 ] && [ "$(q "SELECT result GLOB '\''file:*'\'' FROM jobs WHERE id='\''$job'\''")" = 1 ]'
code=$(status POST "/models/$mdl/iso?value=200")
check "an iso change: 200, version 2, the mesh a new file and the old one gone" \
    '[ "$code" = 200 ] && [ "$(field version)" = 2 ] && [ "$(file_of "SELECT source FROM models WHERE id='\''$mdl'\''")" != "$src" ] && [ ! -e "$V/$src" ]'
code=$(status GET "/models/$mdl/mesh?format=delta&since=1"); cp "$T/body" "$T/d1"
check "its delta since 1: 200, composed from the new mesh's file and kept nowhere (no job)" \
    '[ "$code" = 200 ] && [ "$(head -c 4 "$T/d1")" = SFMD ] && [ "$(q "SELECT count(*) FROM jobs WHERE options LIKE '\''%since=1%'\''")" = 0 ]'
status GET "/models/$mdl/mesh?format=stl" >/dev/null; cp "$T/body" "$T/b.stl"
check "every file some row's, every row's file there" '[ "$(named)" = "$(present)" ]'
stop_daemon

start_daemon "$T/d" || exit 1
check "after a restart: the STL, the first STL's job result and the delta the same bytes" \
    '[ "$(status GET "/models/$mdl/mesh?format=stl")" = 200 ] && cmp -s "$T/body" "$T/b.stl" && [ "$(status GET "/jobs/$job/result")" = 200 ] && cmp -s "$T/body" "$T/a.stl" && [ "$(status GET "/models/$mdl/mesh?format=delta&since=1")" = 200 ] && cmp -s "$T/body" "$T/d1"'
stop_daemon

$S store check --data-dir "$T/d" >"$T/out" 2>&1; rc=$?
check "store check over the files: sound" '[ "$rc" = 0 ] && grep -q "is sound" "$T/out"'
src=$(file_of "SELECT source FROM models WHERE id='$mdl'")
cp "$V/$src" "$T/src.keep"; cp "$V/$vol" "$T/vol.keep"
printf '\377' | dd of="$V/$src" bs=1 seek=1000 conv=notrunc 2>/dev/null
rm "$V/$vol"
$S store check --data-dir "$T/d" >"$T/out" 2>&1; rc=$?
check "a byte of the mesh's file altered, the volume's file gone: store check exit 1, naming both" \
    '[ "$rc" = 1 ] && grep -q "model $mdl: its bytes do not match" "$T/out" && grep -q "model volume $mdl/0: its file or pieces could not be read" "$T/out"'
cp "$T/src.keep" "$V/$src"; cp "$T/vol.keep" "$V/$vol"; chmod 600 "$V/$src" "$V/$vol"

head -c 2000000 /dev/zero >"$V/0123456789abcdef0123456789abcdef"; touch -d '2 hours ago' "$V/0123456789abcdef0123456789abcdef"
head -c 2000000 /dev/zero >"$V/fedcba9876543210fedcba9876543210"
start_daemon "$T/d" || exit 1
check "at start: a stray file of two hours ago swept, one of now kept" \
    '[ ! -e "$V/0123456789abcdef0123456789abcdef" ] && [ -e "$V/fedcba9876543210fedcba9876543210" ]'
rm -f "$V/fedcba9876543210fedcba9876543210"
check "the model deleted: 204, its files with it; its STL job's result stays" \
    '[ "$(status DELETE "/models/$mdl")" = 204 ] && [ ! -e "$V/$src" ] && [ ! -e "$V/$vol" ] && [ "$(named)" = "$(present)" ] && [ "$(present | wc -l)" -ge 1 ] && [ "$(status GET "/jobs/$job/result")" = 200 ] && cmp -s "$T/body" "$T/a.stl"'
stop_daemon
checks_done
