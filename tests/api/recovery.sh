#!/bin/sh
# Black-box regression tests of issue 48's findings 3, 9 and 2 (isosurfaces): the job that stops
# the service is blamed, not the innocent one running beside it (a kill -9 stands for the kernel's
# OOM killer: it strikes whenever the poison job runs); a job cancelled before a stop is not run
# again; and a field whose surface is over max-triangles fails alone with a 422, before its mesh,
# as does a scene whose stored meshes come to more.
. "$(dirname "$0")/lib.inc"

RAW='Content-Type: application/octet-stream'
field() { python3 -c "import json,sys; print(json.load(open(sys.argv[1])).get(sys.argv[2], ''))" "$T/body" "$1"; }
state_of() { curl -s "$URL/jobs/$1" | python3 -c "import json,sys; d=json.load(sys.stdin); print(d['state'], d.get('attempts', ''))"; }
# a striped field: every cell holds surface (N^3 samples, 4 N^3 triangles or so)
checker() {
    python3 -c "
import sys
n = int(sys.argv[1])
a = bytes((i % 2) * 200 for i in range(n)); b = bytes(((i + 1) % 2) * 200 for i in range(n))
sys.stdout.buffer.write(b''.join(a if (y + z) % 2 == 0 else b for z in range(n) for y in range(n)))" "$1" >"$2"
}
checker 96 "$T/c96.raw"

# ---- 3: blame the right job after a crash ----------------------------------------------------------
start_daemon "$T/d1" --threads 2 --max-attempts 2 || exit 1
status POST "/isosurface?dims=96,96,96&type=uint8&iso=100" -H 'Prefer: respond-async' -H "$RAW" --data-binary @"$T/c96.raw" >/dev/null
innocent=$(header X-Job-Id)
status POST "/isosurface?dims=96,96,96&type=uint8&iso=50" -H 'Prefer: respond-async' -H "$RAW" --data-binary @"$T/c96.raw" >/dev/null
poison=$(header X-Job-Id)
# the killer: whenever the poison runs (beside the innocent the first time), kill -9, and start again
kills=0; beside=0
for round in $(seq 8); do
    for _ in $(seq 600); do
        s=$(state_of "$poison"); i=$(state_of "$innocent")
        case "$s" in running*) break ;; failed* | succeeded*) break ;; esac
        sleep 0.05
    done
    case "$s" in running*) ;; *) break ;; esac
    case "$i" in running*) beside=$((beside + 1)) ;; esac
    kill -9 "$PID"; wait "$PID" 2>/dev/null; PID=""; kills=$((kills + 1))
    start_daemon "$T/d1" --threads 2 --max-attempts 2 || exit 1
done
check "the poison ran beside the innocent when it first took the service down" '[ "$beside" -ge 1 ]'
check "... after the restarts, the innocent succeeded (it was failed after 2 stops)" 'wait_state "$innocent" succeeded 120'
check "... and the poison failed alone, charged with its own stops" 'wait_state "$poison" failed 30 && [ "$(status GET "/jobs/$poison/result")" = 500 ] && grep -q "stopped the service 2 times" "$T/body"'
check "... after $kills kills, each restart logged the suspects running alone" 'grep -q "runs alone: it was running when the service last stopped" "$T/all.log" "$T/daemon.log"'

# ---- 9: a job cancelled before the service stops is not run again ----------------------------------
status POST "/isosurface?dims=96,96,96&type=uint8&iso=100&levels=2" -H 'Prefer: respond-async' -H "$RAW" --data-binary @"$T/c96.raw" >/dev/null
long=$(header X-Job-Id)
for _ in $(seq 200); do state_of "$long" | grep -q running && break; sleep 0.05; done
# the cancel reaches the store (cancel_requested), then the node is killed before the job stops
status POST "/jobs/$long/cancel" >/dev/null
kill -9 "$PID"; wait "$PID" 2>/dev/null; PID=""
start_daemon "$T/d1" --threads 2 --max-attempts 2 || exit 1
check "a job cancelled, then kill -9: cancelled at the restart, not queued again" 'wait_state "$long" cancelled 10 && grep -q "was cancelled before the service stopped" "$T/daemon.log"'

# ---- 9: an FRep whose sampling is hours of work stops at its cancel (polled a block of 8^3 samples at a time) ----
python3 -c "
import json, random
random.seed(48)
objs = [{'superellipsoid': {'center': [random.uniform(-9, 9) for _ in range(3)], 'radii': [random.uniform(0.3, 1.5) for _ in range(3)],
                            'e1': random.uniform(0.3, 2), 'e2': random.uniform(0.3, 2)}} for _ in range(512)]
print(json.dumps({'bounds': [[-10, -10, -10], [10, 10, 10]], 'cell': 0.05, 'frep': {'union': objs}}))" >"$T/union.json"
status POST /isosurface -H 'Prefer: respond-async' -H 'Content-Type: application/json' --data-binary @"$T/union.json" >/dev/null
big=$(header X-Job-Id)
for _ in $(seq 200); do state_of "$big" | grep -q running && break; sleep 0.05; done
sleep 1
t0=$(date +%s%N)
status POST "/jobs/$big/cancel" >/dev/null
wait_state "$big" cancelled 30; took=$((($(date +%s%N) - t0) / 1000000))
echo "an FRep cancelled while sampling ended after $took ms"
check "a union of 512 superellipsoids on 64 M samples, cancelled while sampling: cancelled (it ran on for hours)" '[ "$(state_of "$big" | cut -d" " -f1)" = cancelled ]'

# ---- 10a: an edit is applied once, even when its job runs again after a crash --------------------
# the state a kill -9 leaves between an edit's store and its job's end, made with sqlite3 while the
# daemon is stopped: the edit stored, its job still running on a node that is gone
python3 -c "
import struct, sys
n = 24
v = [200 if (x-12)**2 + (y-12)**2 + (z-12)**2 < 64 else 0 for z in range(n) for y in range(n) for x in range(n)]
sys.stdout.buffer.write(struct.pack('<%dh' % len(v), *v))" >"$T/ball.raw"
python3 -c "import struct, sys; sys.stdout.buffer.write(struct.pack('<512h', *([300] * 512)))" >"$T/cube.raw"
python3 -c "import struct, sys; sys.stdout.buffer.write(struct.pack('<512h', *([0] * 512)))" >"$T/hole.raw"
status POST "/isosurface?dims=24,24,24&type=int16&iso=100" -H "$RAW" --data-binary @"$T/ball.raw" >/dev/null; mdl=$(field id)
status POST "/models/$mdl/edit?region=2,2,2,8,8,8" -H "$RAW" --data-binary @"$T/cube.raw" >/dev/null; a=$(header X-Job-Id)
check "edit A (a cube of bone): edits 1" '[ -n "$a" ] && [ "$(field edits)" = 1 ]'
stop_daemon
sqlite3 "$T/d1/surfd.db" "UPDATE jobs SET state='running', node='gone', lease_until=0, finished=0 WHERE id='$a'"
start_daemon "$T/d1" --threads 2 --max-attempts 2 || exit 1
code=$(status POST "/models/$mdl/edit?region=2,2,2,8,8,8" -H "$RAW" --data-binary @"$T/hole.raw"); bvol=$(field volume_mm3)
check "edit B of the same region, answered after the restart: edits 2" '[ "$code" = 200 ] && [ "$(field edits)" = 2 ]'
check "A, run again after the restart, succeeds ..." 'wait_state "$a" succeeded 30'
check "... without being applied again (edits stay 2, B's surface stays: it undid B)" '[ "$(status GET "/models/$mdl")" = 200 ] && [ "$(field edits)" = 2 ] && python3 -c "import sys; a, b = map(float, sys.argv[1:]); sys.exit(abs(a - b) > 1e-9 * abs(a))" "$(field volume_mm3)" "$bvol" && grep -q "not applied again" "$T/daemon.log"'
stop_daemon

# ---- 2: over max-triangles: a 422 before the mesh is made, for either extraction --------------------
start_daemon "$T/d2" --threads 2 --max-triangles 100000 || exit 1
for q in "" "&levels=2"; do
    code=$(status POST "/isosurface?dims=96,96,96&type=uint8&iso=100$q" -H "$RAW" --data-binary @"$T/c96.raw")
    check "a striped field of 3.5 M triangles, max-triangles 100 000 [${q:-levels=1}]: 422 naming the cap" '[ "$code" = 422 ] && is_problem 422 && grep -q "max-triangles" "$T/body"'
done
code=$(status POST "/isosurface?dims=24,24,24&type=int16&iso=100" -H "$RAW" --data-binary @"$T/ball.raw")
check "... a ball under the cap is made as ever" '[ "$code" = 201 ] && [ "$(field boundary_edges)" = 0 ]'
ball=$(field id); bt=$(field triangles)
# a scene names the ball's mesh once a reference: 100 000 / its triangles references fit, one more does not
fit=$((100000 / bt))
scene() { python3 -c "import json, sys; print(json.dumps({'objects': [{'type': 'model', 'id': sys.argv[1]}] * int(sys.argv[2])}))" "$ball" "$1" >"$T/scene.json"; }
scene "$fit"
check "a scene naming the ball $fit times ($((fit * bt)) triangles): rendered" '[ "$(status POST "/render?width=32&height=32" -H "Content-Type: application/json" --data-binary @"$T/scene.json")" = 200 ]'
scene 50
code=$(status POST "/render?width=32&height=32" -H "Content-Type: application/json" --data-binary @"$T/scene.json")
check "... naming it 50 times: 422 at the reference past the cap, with the figure" '[ "$code" = 422 ] && is_problem 422 && grep -q "\"pointer\":\"/objects/$fit/id\"" "$T/body" && grep -q "max-triangles" "$T/body"'
check "the daemon is up" 'alive'

finish
