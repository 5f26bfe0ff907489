#!/bin/sh
# Black-box regression tests of issue 48's finding 10e: a damaged store is not served as if it
# were sound. At start the store checks its pages (PRAGMA quick_check) and every model's sums, and
# refuses to serve on damage with a log line naming what; a read that finds damage while serving
# answers 500 (not 200 with an empty or altered list) and makes /readyz 503; `surfd store check`
# is the operator's look (exit 0 sound, 1 damaged), naming each damaged job, model or volume, and
# `surfd store recover` keeps the sound part. Commits lost from a truncated WAL are found (a
# kill -9 loses none, so a WAL that holds fewer frames than its last commit left was cut).
. "$(dirname "$0")/lib.inc"

RAW='Content-Type: application/octet-stream'
DB="$T/d/surfd.db"
python3 -c "
import sys
sys.stdout.buffer.write(bytes(200 if 2 < x < 6 and 2 < y < 6 and 2 < z < 6 else 0 for z in range(8) for y in range(8) for x in range(8)))" >"$T/cube.raw"

start_daemon "$T/d" || exit 1
for k in 1 2 3; do
    status POST "/isosurface?dims=8,8,8&type=uint8&iso=$((90 + k))" -H "$RAW" --data-binary @"$T/cube.raw" >/dev/null
done
victim=$(header Location | sed 's,.*/,,')
stop_daemon
cp "$DB" "$T/clean.db"

$S store check --data-dir "$T/d" >"$T/out" 2>&1; rc=$?
check "store check on a sound store: exit 0, 'sound'" '[ "$rc" = 0 ] && grep -q "is sound" "$T/out"'

# a model's resource changed behind the store's back (its sums kept): the service does not start
sqlite3 "$DB" "UPDATE models SET resource = replace(resource, '\"name\":\"\"', '\"name\":\"altered\"') WHERE id = '$victim'"
$S store check --data-dir "$T/d" >"$T/out" 2>&1; rc=$?
# (once: the resource's own sum; the mesh's sum covers the mesh alone, which each edit leaves as it is)
check "store check on a model whose bytes do not match their sum: exit 1, naming that model (and only it)" \
    '[ "$rc" = 1 ] && grep -q "model $victim: its bytes do not match" "$T/out" && [ "$(grep -c "do not match" "$T/out")" = 1 ]'
$S serve --listen 127.0.0.1:0 --data-dir "$T/d" >"$T/serve.log" 2>&1 & spid=$!
for _ in $(seq 100); do kill -0 "$spid" 2>/dev/null || break; sleep 0.05; done
wait "$spid"; rc=$?
check "... serve refuses to start on it, with a log line naming the model" \
    '! kill -0 "$spid" 2>/dev/null && [ "$rc" != 0 ] && grep -q "store check: model $victim" "$T/serve.log" && grep -q "is damaged: not starting" "$T/serve.log"'

$S store recover --data-dir "$T/d" >"$T/out" 2>&1; rc=$?
check "store recover: exit 0, a copy kept, that model (and only it) removed" \
    '[ "$rc" = 0 ] && grep -q "kept the store as it was in .*surfd.db.before-recover-" "$T/out" && grep -q "model $victim: removed" "$T/out" && [ "$(grep -c ": removed" "$T/out")" = 1 ] && grep -q "is mended" "$T/out"'
check "... the copy is the service user's alone, and holds the model" \
    'c=$(ls "$T"/d/surfd.db.before-recover-*) && [ "$(stat -c %a "$c")" = 600 ] && [ "$(sqlite3 "$c" "SELECT count(*) FROM models")" = 3 ]'
$S store check --data-dir "$T/d" >"$T/out" 2>&1; rc=$?
check "... and the store left is sound: check exit 0, two models" '[ "$rc" = 0 ] && [ "$(sqlite3 "$DB" "SELECT count(*) FROM models")" = 2 ]'
rm -f "$T"/d/surfd.db.before-recover-*

# a damaged page: the jobs table's root (page 2) overwritten
cp "$T/clean.db" "$DB"
printf '\377\377\377\377\377\377\377\377' | dd of="$DB" bs=1 seek=4096 conv=notrunc 2>/dev/null
$S store check --data-dir "$T/d" >"$T/out" 2>&1; rc=$?
check "store check on a damaged page: exit 1, SQLite's finding printed" '[ "$rc" = 1 ] && grep -q "Page 2" "$T/out"'
$S serve --listen 127.0.0.1:0 --data-dir "$T/d" >"$T/serve.log" 2>&1; rc=$?
check "... serve refuses to start on it" '[ "$rc" != 0 ] && grep -q "is damaged: not starting" "$T/serve.log"'
$S store recover --data-dir "$T/d" >"$T/out" 2>&1; rc=$?
check "... store recover does not pretend to mend pages: exit 1, restore a backup" '[ "$rc" = 1 ] && grep -q "restore a backup" "$T/out"'

# damage found while serving: a model altered under the running service
cp "$T/clean.db" "$DB"
start_daemon "$T/d" || exit 1
check "the sound store serves: /readyz 200, three models" '[ "$(status GET /readyz)" = 200 ] && [ "$(status GET /models)" = 200 ] && [ "$(grep -o "\"id\"" "$T/body" | wc -l)" = 3 ]'
sqlite3 "$DB" "UPDATE models SET resource = replace(resource, '\"name\":\"\"', '\"name\":\"altered\"') WHERE id = '$victim'"
check "GET /models over an altered model: 500 problem, not the altered bytes" '[ "$(status GET /models)" = 500 ] && is_problem 500 && ! grep -q altered "$T/body"'
check "GET /models/ID of it: 500, damaged" '[ "$(status GET "/models/$victim")" = 500 ] && grep -qi "damaged" "$T/body"'
check "... and /readyz is then 503, saying why" '[ "$(status GET /readyz)" = 503 ] && grep -q "store is damaged" "$T/body"'
check "... the damage is logged" 'grep -qi "damaged" "$T/daemon.log"'
stop_daemon

# ---- commits lost from the WAL: a kill -9 loses none; a WAL truncated behind the store is found
rm -rf "$T/w"
start_daemon "$T/w" || exit 1
post_three() {
    for k in 1 2 3; do
        status POST "/isosurface?dims=8,8,8&type=uint8&iso=$((90 + k))" -H "$RAW" --data-binary @"$T/cube.raw" >/dev/null
    done
}
models() { status GET /models >/dev/null; grep -o '"id"' "$T/body" | wc -l; }
post_three
kill -9 "$PID"; wait "$PID" 2>/dev/null; PID=""
check "after a kill -9 the WAL holds the commits" '[ -s "$T/w/surfd.db-wal" ]'
start_daemon "$T/w" || exit 1
check "... the store starts on it (no loss found where there is none), its 3 models served" '[ "$(models)" = 3 ] && [ "$(status GET /readyz)" = 200 ]'
post_three
kill -9 "$PID"; wait "$PID" 2>/dev/null; PID=""
# half the frames of the WAL's current run: after a checkpoint SQLite writes the WAL again from its
# start, so the file's tail may hold an older run's frames (their salts not the header's) and half
# the file's size need not cut the last run at all
cut=$(python3 - "$T/w/surfd.db-wal" <<'PY'
import struct, sys
d = open(sys.argv[1], "rb").read()
ps, salt = struct.unpack(">I", d[8:12])[0], d[16:24]
n = 0
while 32 + (n + 1) * (ps + 24) <= len(d) and d[32 + n * (ps + 24) + 8:32 + n * (ps + 24) + 16] == salt:
    n += 1
print(32 + (n // 2) * (ps + 24))
PY
)
truncate -s "$cut" "$T/w/surfd.db-wal"
$S store check --data-dir "$T/w" >"$T/out" 2>&1; rc=$?
check "the WAL truncated to half: store check exit 1, naming the frames lost" \
    '[ "$rc" = 1 ] && grep -q "the WAL (surfd.db-wal) holds [0-9]* valid frames of the [0-9]* its last commit left" "$T/out"'
$S serve --listen 127.0.0.1:0 --data-dir "$T/w" >"$T/serve.log" 2>&1; rc=$?
check "... serve refuses to start on it, saying so (was: half the jobs and models silently gone)" \
    '[ "$rc" != 0 ] && grep -q "valid frames of the" "$T/serve.log" && grep -q "is damaged: not starting" "$T/serve.log"'
$S serve --listen 127.0.0.1:0 --data-dir "$T/w" >"$T/serve.log" 2>&1; rc=$?
check "... and again: the loss is remembered, not forgotten at the next start" '[ "$rc" != 0 ] && grep -q "valid frames of the" "$T/serve.log"'
$S store recover --data-dir "$T/w" >"$T/out" 2>&1; rc=$?
check "store recover accepts the store as it is: exit 0" '[ "$rc" = 0 ] && grep -q "^accepted: the WAL" "$T/out" && grep -q "is mended" "$T/out"'
start_daemon "$T/w" || exit 1
n=$(models)
check "... the service starts, serving what the WAL kept ($n of 6 models)" '[ "$n" -ge 3 ] && [ "$n" -lt 6 ] && [ "$(status GET /readyz)" = 200 ]'
finish
