#!/bin/sh
# Frames a second of the page's 3D view while it turns (issue 46), in headless Chromium on
# SwiftShader (software WebGL: no GPU), 1280x800: the heart contour model, then every ROI of the
# dicompyler RT Structure Set together. Not part of make test (timings are noisy).
# Usage: tests/bench/view_fps.sh [SECONDS]   (SURFD_BIN: the daemon, build/surfd by default)
. "$(dirname "$0")/../api/lib.inc"
DATA="${SURFD_DATA:-../shared/data}/contours"
N=build/npm
[ -d "$N/node_modules/playwright-core" ] || npm install --silent --no-audit --no-fund --prefix "$N" playwright-core@1.65.1 >/dev/null
start_daemon "$T/bench" --threads 2 || exit 1
heart=$(curl -s -H 'Content-Type: application/json' --data-binary @"$DATA/dicompyler_heart.json" "$URL/model" |
    python3 -c 'import json,sys; print(json.load(sys.stdin)["id"])')
rois=$(curl -s -H 'Content-Type: application/dicom' --data-binary @"$DATA/dicompyler-core_example_rtss.dcm" "$URL/model" |
    python3 -c 'import json,sys; print(",".join(m["id"] for m in json.load(sys.stdin)["models"]))')
NODE_PATH="$N/node_modules" URL="$URL" SECONDS_EACH="${1:-5}" node tests/bench/view_fps.mjs "heart contour model=$heart" \
    "RT Structure Set, every ROI=$rois"
