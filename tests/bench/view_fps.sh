#!/bin/sh
# The page's 3D view in headless Chromium on SwiftShader (software WebGL: no GPU), 1280x800 (issue
# 46): frames a second while it turns the heart contour model, every ROI of the dicompyler RT
# Structure Set together, and the CT head's isosurface (678 k triangles); then the time from a
# brush stroke to the updated surface (mouse up -> the edit's request -> its delta applied -> the
# next frame), the median of N strokes on the CT head at levels=1 and at levels=2, and four iso
# changes of each timed the same way. Not part of make test (timings are noisy).
# Usage: tests/bench/view_fps.sh [SECONDS] [STROKES]   (SURFD_BIN: the daemon, build/surfd by default)
. "$(dirname "$0")/../api/lib.inc"
DATA="${SURFD_DATA:-../shared/data}/contours"
CT="${SURFD_DATA:-../shared/data}/volumes/ct_head_256x256x108_int16.raw"
N=build/npm
[ -d "$N/node_modules/playwright-core" ] || npm install --silent --no-audit --no-fund --prefix "$N" playwright-core@1.65.1 >/dev/null
start_daemon "$T/bench" --threads 2 || exit 1
id_of() { python3 -c 'import json,sys; print(json.load(sys.stdin)["id"])'; }
heart=$(curl -s -H 'Content-Type: application/json' --data-binary @"$DATA/dicompyler_heart.json" "$URL/model" | id_of)
rois=$(curl -s -H 'Content-Type: application/dicom' --data-binary @"$DATA/dicompyler-core_example_rtss.dcm" "$URL/model" |
    python3 -c 'import json,sys; print(",".join(m["id"] for m in json.load(sys.stdin)["models"]))')
ct() { # ct LEVELS: the CT head's isosurface at 226.5 (RESULTS.md's), a model of that many levels
    curl -s -H 'Content-Type: application/octet-stream' --data-binary @"$CT" \
        "$URL/isosurface?iso=226.5&dims=256,256,108&type=int16&spacing=0.9570312,0.9570312,1.5&levels=$1&name=CT%20head%2C%20levels%20$1" | id_of
}
ct1=$(ct 1)
echo "models: heart $heart, ROIs $rois, CT $ct1 (levels=1)" >&2
ct2=$(ct 2)
echo "CT $ct2 (levels=2)" >&2
NODE_PATH="$N/node_modules" URL="$URL" SECONDS_EACH="${1:-5}" STROKES="${2:-11}" node tests/bench/view_fps.mjs \
    "heart contour model=$heart" "RT Structure Set, every ROI=$rois" "CT head isosurface at 226.5=$ct1" \
    "brush:CT head levels=1=$ct1" "brush:CT head levels=2=$ct2"
# the daemon's own time for those edits and deltas (its access log): what the page's figures hold
# beside the browser's (software WebGL on the same two cores)
python3 - "$T/daemon.log" "$ct1" "$ct2" <<'PY'
import re, statistics, sys
log = open(sys.argv[1]).read()
for levels, mid in ((1, sys.argv[2]), (2, sys.argv[3])):
    ms = [float(x) for x in re.findall(r"POST /models/%s/edit 200 \d+ ([\d.]+)ms" % mid, log)]
    mesh = [(int(s), int(b), float(t)) for s, b, t in re.findall(r"GET /models/%s/mesh (\d+) (\d+) ([\d.]+)ms" % mid, log)]
    iso = [float(x) for x in re.findall(r"POST /models/%s/iso 200 \d+ ([\d.]+)ms" % mid, log)]
    line = "daemon, CT head levels=%d: %d edits, median %.1f ms;" % (levels, len(ms), statistics.median(ms)) if ms else ""
    line += " %d iso changes, median %.1f ms;" % (len(iso), statistics.median(iso)) if iso else ""
    # (over 10 MB: the opening loads, the reloads after a 410, and an iso change's delta, every triangle new)
    for what, xs in (("mesh answers over 10 MB", [m for m in mesh if m[0] == 200 and m[1] > 1e7]),
                     ("smaller deltas", [m for m in mesh if m[0] == 200 and m[1] <= 1e7]),
                     ("410s", [m for m in mesh if m[0] == 410])):
        if xs:
            line += " %d %s, median %.1f ms, %d bytes;" % (len(xs), what, statistics.median(x[2] for x in xs), statistics.median(x[1] for x in xs))
    print(line)
PY
