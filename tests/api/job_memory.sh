#!/bin/sh
# Issue 48's per-job memory budget (job-memory): each job's own allocations are charged to it
# (daemon/memwrap.c, core/base/mem.h) and refused past its budget, so a job that outgrows it fails
# alone with a 422 naming the budget while the jobs beside it run on; an isosurface whose mesh
# would not fit (some 80 bytes a triangle) is refused before it is made, as is one that would make
# more triangles than its request's size allows (max-triangles-per-byte).
. "$(dirname "$0")/lib.inc"

RAW='Content-Type: application/octet-stream'
field() { python3 -c "import json,sys; print(json.load(open(sys.argv[1])).get(sys.argv[2], ''))" "$T/body" "$1"; }
# a striped field: every cell holds surface (96^3 samples, 3.5 M triangles)
python3 -c "
import sys
n = 96
a = bytes((i % 2) * 200 for i in range(n)); b = bytes(((i + 1) % 2) * 200 for i in range(n))
sys.stdout.buffer.write(b''.join(a if (y + z) % 2 == 0 else b for z in range(n) for y in range(n)))" >"$T/c96.raw"
python3 -c "
import struct, sys
n = 48
v = [200 if (x-24)**2 + (y-24)**2 + (z-24)**2 < 400 else 0 for z in range(n) for y in range(n) for x in range(n)]
sys.stdout.buffer.write(struct.pack('<%dh' % len(v), *v))" >"$T/ball.raw"
# an FRep sphere on 400^3 samples: 256 MB of floats, declared in 80 bytes
echo '{"bounds": [[-10, -10, -10], [10, 10, 10]], "cell": 0.05, "frep": {"sphere": {"center": [0, 0, 0], "radius": 5}}}' >"$T/big.json"

start_daemon "$T/d" --threads 2 --job-memory 67108864 || exit 1
check "the start line says each worker's budget" 'grep -q "2 workers of 64 MB" "$T/daemon.log"'

# ---- decided before the work: the mesh's triangles against what the budget holds ----------------
code=$(status POST "/isosurface?dims=96,96,96&type=uint8&iso=100" -H "$RAW" --data-binary @"$T/c96.raw")
check "a striped field of 3.5 M triangles (some 280 MB of mesh), job-memory 64 MB: 422 before the mesh, naming job-memory" '[ "$code" = 422 ] && is_problem 422 && grep -q "job-memory" "$T/body" && grep -q "838860" "$T/body"'

# ---- enforced during it: the poison fails alone, the innocents beside it succeed ---------------
status POST /isosurface -H 'Prefer: respond-async' -H 'Content-Type: application/json' --data-binary @"$T/big.json" >/dev/null
poison=$(header X-Job-Id)
code=$(status POST "/isosurface?dims=48,48,48&type=int16&iso=100" -H "$RAW" --data-binary @"$T/ball.raw")
check "an innocent ball beside it: 201, closed" '[ "$code" = 201 ] && [ "$(field boundary_edges)" = 0 ]'
ball=$(field id)
check "an innocent render of the ball beside it: 200" '[ "$(status GET "/models/$ball/render?width=64&height=64")" = 200 ]'
check "the FRep of 400^3 samples (256 MB) fails ..." 'wait_state "$poison" failed 60'
code=$(status GET "/jobs/$poison/result")
check "... with a 422 that names job-memory and the figures" '[ "$code" = 422 ] && is_problem 422 && grep -q "needs more memory than this node gives one job (job-memory, 64 MB)" "$T/body"'
check "... and the daemon is up, not restarted" 'alive && [ "$(grep -c "listening on" "$T/daemon.log")" = 1 ]'
code=$(status POST /isosurface -H 'Content-Type: application/json' --data-binary '{"bounds": [[-10, -10, -10], [10, 10, 10]], "cell": 0.5, "frep": {"sphere": {"center": [0, 0, 0], "radius": 5}}}')
check "the same FRep on 40^3 samples: 201" '[ "$code" = 201 ]'
stop_daemon

# ---- the default: a share of the memory the process may use ------------------------------------
start_daemon "$T/d" --threads 2 || exit 1
mb=$(sed -n 's/.*2 workers of \([0-9]*\) MB.*/\1/p' "$T/daemon.log")
total=$(awk '/MemTotal/ {print int($2 / 1024)}' /proc/meminfo)
check "without job-memory, each of 2 workers gets at most 3/8 of the machine's $total MB (${mb:-?} MB)" '[ -n "$mb" ] && [ "$mb" -gt 0 ] && [ "$mb" -le $((total * 3 / 8 + 1)) ]'
code=$(status POST /isosurface -H 'Content-Type: application/json' --data-binary @"$T/big.json")
check "... which the FRep of 256 MB fits: 201" '[ "$code" = 201 ]'

# ---- what a request's size lets it make (max-triangles-per-byte, 64 a byte, 4 M at least) --------
python3 - "$T" <<'EOF'
import gzip, sys
t = sys.argv[1]
def nrrd(name, n, value):
    raw = bytes(value(x, y, z) for z in range(n) for y in range(n) for x in range(n))
    head = "NRRD0004\ntype: uint8\ndimension: 3\nsizes: %d %d %d\nspacings: 1 1 1\nencoding: gzip\n\n" % (n, n, n)
    open("%s/%s.nrrd" % (t, name), "wb").write(head.encode() + gzip.compress(raw, 9))
nrrd("striped", 112, lambda x, y, z: 200 * ((x + y + z) % 2))  # surface in every cell: some 5.6 M triangles
nrrd("label", 112, lambda x, y, z: 1 if (x - 56)**2 + (y - 56)**2 + (z - 56)**2 < 45**2 else 0)  # a label map's ball
EOF
size=$(wc -c <"$T/striped.nrrd")
code=$(status POST "/isosurface?iso=100" -H 'Content-Type: application/x-nrrd' --data-binary @"$T/striped.nrrd")
check "a ${size}-byte gzip NRRD of a striped field (1.4 M samples): 422 from the count pass, naming max-triangles-per-byte" \
    '[ "$code" = 422 ] && is_problem 422 && grep -q "what a request of $size bytes may make (max-triangles-per-byte, 64 a byte, 4 M at least)" "$T/body"'
code=$(status POST "/isosurface?iso=0.5" -H 'Content-Type: application/x-nrrd' --data-binary @"$T/label.nrrd")
check "a gzip label map of a ball, $(wc -c <"$T/label.nrrd") bytes: 201, closed" '[ "$code" = 201 ] && [ "$(field boundary_edges)" = 0 ]'

# ---- a delta across an iso change, composed on the checks pool under the same budget --------------
python3 -c "
import sys
n = 96
sys.stdout.buffer.write(bytes(200 if (x-48)**2 + (y-48)**2 + (z-48)**2 < 1600 else 0 for z in range(n) for y in range(n) for x in range(n)))" >"$T/b96.raw"
code=$(status POST "/isosurface?dims=96,96,96&type=uint8&iso=100" -H "$RAW" --data-binary @"$T/b96.raw")
big_ball=$(field id); tris=$(field triangles)
status POST "/models/$big_ball/iso?value=150" >/dev/null
stop_daemon
start_daemon "$T/d" --threads 2 --job-memory 1048576 || exit 1
code=$(status GET "/models/$big_ball/mesh?format=delta&since=1")
check "the delta across an iso change of a ball of $tris triangles (some 3 MB to compose), job-memory 1 MB: 422 naming job-memory" \
    '[ "$code" = 422 ] && is_problem 422 && grep -q "job-memory" "$T/body"'
check "... and the daemon serves on: the model's resource 200" '[ "$(status GET "/models/$big_ball")" = 200 ]'

finish
