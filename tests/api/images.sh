#!/bin/sh
# Images for compositing (issue 18): EXR premultiplied (RGB 0 where alpha is 0) unless the request
# gives a background (then opaque over it), alpha only 0 or 1 at one ray a pixel, fractional at the
# silhouettes with ?samples=N (stratified rays: at most N + 1 levels), PNG anti-aliased the same
# way (its edges' steps softened); bad sample counts and bad camera inputs (query and JSON) refused. EXR read back by tests/tools/exr_read.py.
. "$(dirname "$0")/lib.inc"
start_daemon "$T/d" || exit 1
exr_stats() { # exr_stats FILE: "fractional levels rgb_where_transparent alpha_min"
    python3 -c "
import sys; sys.path.insert(0, 'tests/tools'); import exr_read
w, h, c = exr_read.read(sys.argv[1])
A, R, G, B = c['A'], c['R'], c['G'], c['B']
print(sum(1 for a in A if 0 < a < 1), len(set(A)), sum(1 for k, a in enumerate(A) if a == 0 and (R[k] or G[k] or B[k])), min(A))" "$1"
}
code=$(status POST "/render?output=exr&width=160&height=120" -H 'Content-Type: model/x-bpt' --data-binary @"$D/teapot.bpt"); cp "$T/body" "$T/a.exr"
read -r frac lev rgb amin <<EOF_
$(exr_stats "$T/a.exr")
EOF_
check "EXR at one ray a pixel: alpha 0 or 1, premultiplied (RGB 0 where alpha is 0)" '[ "$code" = 200 ] && [ "$frac" = 0 ] && [ "$lev" = 2 ] && [ "$rgb" = 0 ]'
code=$(status POST "/render?output=exr&width=160&height=120&samples=16" -H 'Content-Type: model/x-bpt' --data-binary @"$D/teapot.bpt"); cp "$T/body" "$T/b.exr"
read -r frac lev rgb amin <<EOF_
$(exr_stats "$T/b.exr")
EOF_
check "?samples=16: alpha fractional on the silhouettes (at most 17 levels), still premultiplied" '[ "$code" = 200 ] && [ "$frac" -gt 50 ] && [ "$lev" -le 17 ] && [ "$lev" -gt 8 ] && [ "$rgb" = 0 ]'
python3 -c "
import json, sys
d = json.load(open(sys.argv[1])); d.setdefault('image', {}).update({'background': [0, 0, 1], 'samples': 4, 'format': 'exr', 'width': 80, 'height': 60})
json.dump(d, open(sys.argv[2], 'w'))" "$D/teapot.json" "$T/blue.json"
code=$(status POST /render -H 'Content-Type: application/json' --data-binary @"$T/blue.json"); cp "$T/body" "$T/c.exr"
read -r frac lev rgb amin <<EOF_
$(exr_stats "$T/c.exr")
EOF_
check "a background in the request: opaque (alpha 1 everywhere) over it" '[ "$code" = 200 ] && [ "$amin" = 1.0 ]'
code=$(status POST "/render?width=160&height=120&samples=1" -H 'Content-Type: model/x-bpt' --data-binary @"$D/teapot.bpt"); cp "$T/body" "$T/p1.png"
code=$(status POST "/render?width=160&height=120&samples=9" -H 'Content-Type: model/x-bpt' --data-binary @"$D/teapot.bpt"); cp "$T/body" "$T/p9.png"
tv() { python3 -c "
import sys; sys.path.insert(0, 'tests/tools'); import png_read
w, h, r = png_read.read(sys.argv[1])
print(sum(abs(r[y][x][0] - r[y][x + 1][0]) for y in range(h) for x in range(w - 1)) + sum(abs(r[y][x][0] - r[y + 1][x][0]) for y in range(h - 1) for x in range(w)))" "$1"; }
check "PNG anti-aliased with ?samples=9: the silhouettes' steps softened (total variation down by over 5 %)" '[ "$code" = 200 ] && [ $(( $(tv "$T/p9.png") * 100 )) -lt $(( $(tv "$T/p1.png") * 95 )) ]'
check "?samples=0: 422 at ?samples" '[ "$(status POST "/render?samples=0" -H "Content-Type: model/x-bpt" --data-binary @"$D/teapot.bpt")" = 422 ] && grep -q "?samples" "$T/body"'
check "?samples=65: 422 at ?samples" '[ "$(status POST "/render?samples=65" -H "Content-Type: model/x-bpt" --data-binary @"$D/teapot.bpt")" = 422 ] && grep -q "?samples" "$T/body"'
check "?samples=2.5: 422 at ?samples" '[ "$(status POST "/render?samples=2.5" -H "Content-Type: model/x-bpt" --data-binary @"$D/teapot.bpt")" = 422 ]'
code=$(status POST /render -H 'Content-Type: application/json' --data-binary '{"image": {"samples": 100}, "objects": [{"degree": [1, 1], "points": [[0,0,0],[1,0,0],[0,1,0],[1,1,1]]}]}')
check "image.samples 100: 422 at /image/samples" '[ "$code" = 422 ] && grep -q "/image/samples" "$T/body"'
# ---- the camera's new inputs, bad: a 422 at the field, the daemon still up ------------------------------
P='{"degree": [1, 1], "points": [[0,0,0],[1,0,0],[0,1,0],[1,1,1]]}'
bad_q() { # bad_q QUERY POINTER
    want=$2
    code=$(status POST "/render?$1" -H 'Content-Type: model/x-bpt' --data-binary @"$D/teapot.bpt")
    check "?$1: 422 at $2" '[ "$code" = 422 ] && is_problem 422 && grep -q "\"pointer\":\"$want\"" "$T/body"'
}
bad_q "aovs=normal,depth" "?aovs"
bad_q "view_height=0" "?view_height"
bad_q "fov=180" "?fov"
bad_q "up=0,0" "?up"
bad_q "projection=orthographic&view=%2Bq" "?view"
bad_j() { # bad_j CAMERA POINTER
    want=$2
    code=$(status POST /render -H 'Content-Type: application/json' --data-binary "{\"camera\": $1, \"objects\": [$P]}")
    check "camera $1: 422 at $2" '[ "$code" = 422 ] && is_problem 422 && grep -q "\"pointer\":\"$want\"" "$T/body"'
}
bad_j '{"projection": "fisheye"}' /camera/projection
bad_j '{"view": "+w"}' /camera/view
bad_j '{"view": "+x", "eye": [5, 0, 0], "target": [0, 0, 0]}' /camera/view
bad_j '{"projection": "orthographic", "view_height": -2}' /camera/view_height
check "the daemon is up after them" 'alive'
finish
