#!/bin/sh
# Seconds a binary takes for 400 synchronous small POST /volume jobs in a row (each several commits
# of the embedded store): what the store's per-commit work costs (the WAL mark, issue 48), compared
# by running two builds in turn. Usage: tests/bench/store_commits.sh [BIN] [PORT]
set -u
BIN=${1:-./build/surfd}; PORT=${2:-18300}; D=$(mktemp -d)
trap 'kill $P 2>/dev/null; wait $P 2>/dev/null; rm -rf "$D"' EXIT
$BIN serve --listen 127.0.0.1:"$PORT" --data-dir "$D/d" --threads 2 --log-level error >/dev/null 2>&1 & P=$!
for _ in $(seq 100); do curl -s -o /dev/null "http://127.0.0.1:$PORT/livez" && break; sleep 0.05; done
python3 - "$PORT" <<'PY'
import http.client, json, sys, time
sq = [[0, 0], [10, 0], [10, 10], [0, 10]]
body = json.dumps({"slices": [{"z": 0, "points": sq}, {"z": 1, "points": sq}]}).encode()
c = http.client.HTTPConnection("127.0.0.1", int(sys.argv[1]))
t0 = time.time()
for _ in range(400):
    c.request("POST", "/volume", body=body, headers={"Content-Type": "application/json"})
    r = c.getresponse()
    r.read()
    assert r.status == 200, r.status
print("%.3f" % (time.time() - t0))
PY
