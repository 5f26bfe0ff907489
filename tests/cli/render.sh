#!/bin/sh
# Drives `build/surfd render` as a user would: every scene format, PNG/EXR/TIFF, --stats, the
# three ducks as one scene, and the clear failures (bad file, bad option, unknown method).
. "$(dirname "$0")/lib.inc"

# every shared scene renders to a PNG with content (not just background)
for f in teapot.json teapot.bpt teacup.json teacup.bpt teaspoon.json teaspoon.bpt duck1.nurbs duck2.nurbs duck3.nurbs; do
    $S render "$D/$f" -o "$T/out.png" --width 96 --height 72 --stats 2>"$T/stats" >/dev/null
    check "render $f" '[ $? -eq 0 ] && [ "$(head -c 8 "$T/out.png" | od -An -tx1 | tr -d " \n")" = "89504e470d0a1a0a" ]'
    check "stats $f" 'grep -q "\"render_ms\":" "$T/stats" && grep -q "\"iterations_mean\":" "$T/stats" && ! grep -q "\"hits\":0," "$T/stats"'
done

# all three ducks in one scene
$S render "$D/duck1.nurbs" "$D/duck2.nurbs" "$D/duck3.nurbs" -o "$T/ducks.png" --width 96 --height 72 --stats 2>"$T/stats"
check "three ducks" 'grep -q "\"patches\":" "$T/stats" && [ -s "$T/ducks.png" ]'

# every method by name
for m in auto map bvh mesh montecarlo; do
    $S render "$D/teaspoon.bpt" -o "$T/m.png" --width 40 --height 30 --method $m --stats 2>"$T/stats"
    check "method $m" "[ \$? -eq 0 ] && grep -q '\"method\":\"$m\"' \"$T/stats\""
done

# EXR with depth and AOVs: the channel names stand in the header
$S render "$D/teapot.json" -o "$T/t.exr" --width 64 --height 48 --aovs normal,uv,id
check "exr magic" '[ "$(head -c 4 "$T/t.exr" | od -An -tx1 | tr -d " \n")" = "762f3101" ]'
check "exr channels" 'for c in R G B A Z N.x N.y N.z u v id; do head -c 2000 "$T/t.exr" | grep -aq "$c" || exit 1; done'
$S render "$D/teapot.json" -o "$T/t.tif" --width 32 --height 24
check "tiff" '[ -s "$T/t.tif" ]'

# failures: exit codes and messages
$S render "$D/missing.json" -o "$T/x.png" 2>"$T/err"; rc=$?
check "missing file exits 1" '[ $rc -eq 1 ] && grep -q "No such file" "$T/err"'
printf '{"objects":[{"degree":[1,1],"points":[[0,0,0]]}]}' >"$T/bad.json"
$S render "$T/bad.json" -o "$T/x.png" 2>"$T/err"; rc=$?
check "bad scene names the field" '[ $rc -eq 1 ] && grep -q "/objects/0/points" "$T/err"'
$S render "$D/teapot.json" -o "$T/x.gif" 2>/dev/null; rc=$?
check "unknown output format" '[ $rc -eq 2 ]'
$S render "$D/teapot.json" -o "$T/x.png" --method fast 2>/dev/null; rc=$?
check "unknown method" '[ $rc -eq 2 ]'
$S render "$D/teapot.json" 2>/dev/null; rc=$?
check "missing -o" '[ $rc -eq 2 ]'
$S render "$D/teapot.json" -o "$T/x.png" --width 20000 2>"$T/err"; rc=$?
check "image too large" '[ $rc -eq 1 ] && grep -q "/image" "$T/err"'

checks_done
