#!/bin/sh
# `surfd volume` as a user runs it: JSON figures for real and synthetic contours, clear failures.
set -u
cd "$(dirname "$0")/../.." || exit 1
S=./build/surfd
C="${SURFD_DATA:-../shared/data}/contours"
T=$(mktemp -d); trap 'rm -rf "$T"' EXIT
pass=0; fail=0
check() { if eval "$2"; then pass=$((pass + 1)); else fail=$((fail + 1)); echo "FAIL: $1"; fi; }

for f in synthetic_ellipsoid synthetic_bean synthetic_torus_branching dicompyler_heart dicompyler_tumor_bed \
         dicompyler_lt_lung_multicontour eclipse_bladder eclipse_ptv eclipse_rectum eclipse_femoral_head_lt eclipse_body; do
    $S volume "$C/$f.json" >"$T/out" 2>"$T/err"
    check "volume $f" '[ $? -eq 0 ] && grep -q "\"volume_mm3\":[1-9]" "$T/out" && grep -q "\"trapezoid\":" "$T/out" && grep -q "\"caps\":\"flat\"" "$T/out"'
done
printf '{"slices":[{"z":0,"contours":[{"points":[[0,0],[2,0],[0,2]]},{"points":[[1,-1],[1,3],[-1,1]]}]},{"z":1,"points":[[0,0],[1,0],[0,1]]}]}' >"$T/o.json"
$S volume "$T/o.json" >/dev/null 2>"$T/err"; rc=$?
check "overlapping contours on one slice" '[ $rc -eq 1 ] && grep -q "/slices/0/contours/1/points" "$T/err"'
printf '{"slices":[{"z":0,"points":[[0,0],[1,1],[1,0],[0,1]]},{"z":1,"points":[[0,0],[1,0],[0,1]]}]}' >"$T/x.json"
$S volume "$T/x.json" >/dev/null 2>"$T/err"; rc=$?
check "self-crossing contour" '[ $rc -eq 1 ] && grep -q "crosses itself" "$T/err" && grep -q "at /slices/0/points" "$T/err"'
$S volume "$T/none.json" 2>/dev/null; rc=$?
check "missing file" '[ $rc -eq 1 ]'
$S volume 2>/dev/null; rc=$?
check "usage" '[ $rc -eq 2 ]'
echo "$pass passed, $fail failed"
[ "$fail" -eq 0 ]
