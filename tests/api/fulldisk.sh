#!/bin/sh
# Black-box regression test of issue 48's finding 10b: a full disk is a reason to wait, not to
# fail. The data dir is a 96 MB tmpfs (the tests run as root, as CI does), filled to within 1 MB
# while an isosurface whose mesh needs more is accepted: the job waits (not failed), /readyz says
# 503 while the store cannot take writes, and once room returns the job runs again and succeeds.
. "$(dirname "$0")/lib.inc"

RAW='Content-Type: application/octet-stream'
SMALL="$T/small"
mkdir -p "$SMALL"
if ! mount -t tmpfs -o size=96m tmpfs "$SMALL" 2>"$T/mount.err"; then
    bad "a 96 MB tmpfs for the data dir could not be mounted (root is needed): $(cat "$T/mount.err")"
    checks_done; exit 1
fi
trap 'stop_daemon; umount "$SMALL" 2>/dev/null; rm -rf "$T"' EXIT
state_of() { curl -s "$URL/jobs/$1" | python3 -c "import json,sys; print(json.load(sys.stdin)['state'])"; }
# a striped field of 40^3: 250 000 triangles or so, a mesh of some 9 MB
python3 -c "
import sys
n = 40
a = bytes((i % 2) * 200 for i in range(n)); b = bytes(((i + 1) % 2) * 200 for i in range(n))
sys.stdout.buffer.write(b''.join(a if (y + z) % 2 == 0 else b for z in range(n) for y in range(n)))" >"$T/c40.raw"

start_daemon "$SMALL/d" --threads 2 || exit 1
check "with room: /readyz 200" '[ "$(status GET /readyz)" = 200 ]'
# fill the disk to within 1 MB
avail=$(df -B1 --output=avail "$SMALL" | tail -n 1)
dd if=/dev/zero of="$SMALL/filler" bs=1M count=$((avail / 1048576 - 1)) 2>/dev/null
code=$(status POST "/isosurface?dims=40,40,40&type=uint8&iso=100" -H 'Prefer: respond-async' -H "$RAW" --data-binary @"$T/c40.raw")
job=$(header X-Job-Id)
check "an isosurface posted with 1 MB left is accepted (202)" '[ "$code" = 202 ] && [ -n "$job" ]'
for _ in $(seq 200); do grep -q "the disk is full" "$T/daemon.log" && break; sleep 0.1; done
check "... its mesh does not fit: the job waits, logged, not failed" 'grep -q "job $job: the disk is full" "$T/daemon.log" && [ "$(state_of "$job")" != failed ]'
check "... /readyz is 503 while the store cannot take writes" '[ "$(status GET /readyz)" = 503 ]'
sleep 6
check "... still not failed after the first retry's time" '[ "$(state_of "$job")" != failed ] && [ "$(status GET /readyz)" = 503 ]'
rm -f "$SMALL/filler"
check "room again: the job runs again and succeeds" 'wait_state "$job" succeeded 60'
check "... its model is stored whole" '[ "$(status GET "/jobs/$job/result")" = 201 ] && grep -q "\"boundary_edges\":0" "$T/body"'
check "... and /readyz is 200" '[ "$(status GET /readyz)" = 200 ]'
finish
