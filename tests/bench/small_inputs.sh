#!/bin/sh
# The largest memory an input under 64 KB costs the release daemon (issue 48's figure): each
# input to a fresh daemon, its peak RSS (VmHWM) and answer. Inputs: gzip NRRDs of a striped field
# (every cell holds surface) just under and just over max-triangles (40 M), the first under a
# job-memory of 1 GB (what its mesh would need is refused from the count pass), and with
# max-triangles-per-byte off (0), what it cost before that default; an FRep on the most samples an
# FRep may have (its grid is what an 80-byte request may cost); an IGES part of two
# uses of a 2.8 M-point loop whose points crowd together (tests/tools/iges_hostile.py) sent to
# /volume. (A scene naming one model 50 times and a DICOM part of 10 000 nested sequences are
# refused before any work: tests/api/hardening.sh and hostile_dicom.sh.)
# Usage: tests/bench/small_inputs.sh   (make bench runs it: bench.py's small_inputs_bench, BENCH_ONLY=small)
set -u
cd "$(dirname "$0")/../.." || exit 1
S=./build/surfd
T=$(mktemp -d)
trap 'kill $PID 2>/dev/null; rm -rf "$T"' EXIT
nrrd() { # nrrd N FILE: an N^3 uint8 striped field, gzip-encoded
    python3 - "$1" "$2" <<'PY'
import gzip, sys
n, out = int(sys.argv[1]), sys.argv[2]
a = bytes((i % 2) * 200 for i in range(n)); b = bytes(((i + 1) % 2) * 200 for i in range(n))
raw = b''.join(a if (y + z) % 2 == 0 else b for z in range(n) for y in range(n))
head = "NRRD0004\ntype: uint8\ndimension: 3\nsizes: %d %d %d\nspacings: 1 1 1\nencoding: gzip\n\n" % (n, n, n)
open(out, "wb").write(head.encode() + gzip.compress(raw, 9))
PY
}
run() { # run NAME FILE CURL-ARGS...: a fresh daemon, one request, its peak
    name=$1 file=$2; shift 2
    # shellcheck disable=SC2086
    rm -rf "$T/d"; $S serve --listen 127.0.0.1:0 --data-dir "$T/d" --log-level warn ${SERVE_ARGS:-} >"$T/log" 2>&1 & PID=$!
    for _ in $(seq 100); do port=$(sed -n 's/.*listening on http:\/\/127.0.0.1:\([0-9]*\).*/\1/p' "$T/log"); [ -n "$port" ] && break; sleep 0.05; done
    [ -z "$port" ] && { $S serve --listen 127.0.0.1:0 --data-dir "$T/d2" --log-level info >"$T/log" 2>&1 & PID=$!; sleep 0.5; port=$(sed -n 's/.*listening on http:\/\/127.0.0.1:\([0-9]*\).*/\1/p' "$T/log"); }
    t0=$(date +%s.%N)
    code=$(curl -s -o "$T/body" -w '%{http_code}' "$@" --data-binary @"$file" "http://127.0.0.1:$port$URLPATH")
    t1=$(date +%s.%N)
    hwm=$(sed -n 's/VmHWM:\s*\([0-9]*\) kB/\1/p' /proc/$PID/status)
    printf '| %s | %s B | %s | %.1f s | %s MB |\n' "$name" "$(wc -c <"$file")" "$code" "$(echo "$t1 - $t0" | bc)" "$((hwm / 1024))"
    [ "$code" -ge 500 ] && { head -c 300 "$T/body"; echo; tail -3 "$T/log"; }
    kill $PID; wait $PID 2>/dev/null
}
echo "| input | size | answer | time | peak RSS |"
echo "|---|---|---|---|---|"
nrrd 214 "$T/under.nrrd"; nrrd 218 "$T/over.nrrd"
URLPATH="/isosurface?iso=100" run "striped field 214^3, 39.2 M triangles" "$T/under.nrrd" -H 'Content-Type: application/x-nrrd'
URLPATH="/isosurface?iso=100" run "striped field 218^3, 41.4 M triangles (over max-triangles)" "$T/over.nrrd" -H 'Content-Type: application/x-nrrd'
SERVE_ARGS="--max-triangles-per-byte 0" URLPATH="/isosurface?iso=100" run "striped field 214^3, max-triangles-per-byte 0" "$T/under.nrrd" -H 'Content-Type: application/x-nrrd'
SERVE_ARGS="--job-memory 1073741824" URLPATH="/isosurface?iso=100" run "striped field 214^3, job-memory 1 GB" "$T/under.nrrd" -H 'Content-Type: application/x-nrrd'
python3 tests/tools/iges_hostile.py "$T/crowded.igs" 2
URLPATH="/volume?format=iges" run "IGES part, two uses of a 2.8 M-point loop crowded into few cells, /volume" "$T/crowded.igs"
echo '{"bounds": [[-10, -10, -10], [10, 10, 10]], "cell": 0.0311, "frep": {"sphere": {"center": [0, 0, 0], "radius": 9}}}' >"$T/frep.json"
URLPATH="/isosurface" run "FRep sphere on 644^3 samples (FREP_MAX_SAMPLES is 2^28)" "$T/frep.json" -H 'Content-Type: application/json'
