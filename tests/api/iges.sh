#!/bin/sh
# IGES parts over HTTP (issue 17): trimmed NURBS rendered by every method against Open CASCADE's
# triangulation of the same file (tests/tools/occt_iges: masks and depths along the same pixel
# rays: nothing drawn that the trims cut away, no holes inside), trimmed areas and the mug's volume
# against OCCT's and the analytic figures of hand-made parts (tests/tools/iges_write.py: every
# entity the reader takes, and a part's 144 a 402 group's logically dependent member, as CAD systems
# write them), and every kind of broken file as it occurs in the wild refused with the
# entity's directory line, the daemon up after all of them.
. "$(dirname "$0")/lib.inc"
OCCT=build/tests/tools/occt_iges
[ -x "$OCCT" ] || { bad "$OCCT is not built (make test builds it; deploy/install-deps.sh installs Open CASCADE)"; checks_done; exit 1; }
[ -f "$D/mug_solid.igs" ] || { bad "no shared data at $D"; checks_done; exit 1; }
start_daemon "$T/d" || exit 1
python3 tests/tools/iges_write.py "$T" >"$T/areas"

# compare SURFD.exr OCCT.f32: "pixels surfd_only occt_only depth_p99" (depth relative, where both hit)
compare() {
    python3 -c "
import math, struct, sys
sys.path.insert(0, 'tests/tools'); import exr_read
w, h, c = exr_read.read(sys.argv[1]); z = c['Z']
o = struct.unpack('%df' % (w * h), open(sys.argv[2], 'rb').read())
fin = math.isfinite
d = sorted(abs(a - b) / b for a, b in zip(z, o) if fin(a) and fin(b)) or [0]
print(sum(map(fin, o)), sum(1 for a, b in zip(z, o) if fin(a) and not fin(b)),
      sum(1 for a, b in zip(z, o) if fin(b) and not fin(a)), '%.2e' % d[int(0.99 * (len(d) - 1))])" "$1" "$2"
}
# view FILE EYE TARGET UP NAME [METHOD]: surfd's render over HTTP against OCCT's raster
view() {
    file=$1 eye=$2 target=$3 up=$4 name=$5 method=${6:-auto}
    "$OCCT" "$file" --raster 160 160 "$eye" "$target" "$up" 30 0.005 "$T/$name.f32" >/dev/null
    code=$(status POST "/render?format=iges&output=exr&width=160&height=160&eye=$eye&target=$target&up=$up&fov=30&method=$method" \
        --data-binary @"$file")
    cp "$T/body" "$T/$name.exr"
    read -r px so oo dz <<EOF_
$(compare "$T/$name.exr" "$T/$name.f32")
EOF_
    check "$name ($method): $px pixels as OCCT's triangulation, $so drawn where OCCT has none, $oo missing, depth p99 $dz" \
        '[ "$code" = 200 ] && [ "$px" -gt 1000 ] && [ "$so" -le $((px / 500)) ] && [ "$oo" -le $((px / 500)) ] && python3 -c "import sys; sys.exit(float(sys.argv[1]) > 1e-3)" "$dz"'
}
MS="$D/mug_solid.igs"
for m in auto map bvh mesh; do
    view "$MS" 250,-300,220 0,0,40 0,0,1 "mug_solid_side" "$m"
done
view "$MS" 40,-60,330 0,0,20 0,0,1 "mug_solid_into" # into the cup: its inner wall and floor, trimmed by the handle's roots
view "$MS" -150,-200,-120 20,0,50 0,0,1 "mug_solid_under"
view "$D/mug.iges" 300,-250,260 0,0,40 0,0,1 "mug_sheet" # a sheet of two surfaces, the handle's boundary in model space only
view "$T/plate_square.igs" 60,70,330 60,70,30 0,1,0 "plate_square" # moved by a 124: 100 mm plate at (10, 20, 30)
view "$T/plate_model.igs" 50,50,300 50,50,0 0,1,0 "plate_model"

# ---- areas and the volume ---------------------------------------------------------------------------
occt() { "$OCCT" "$1" | tail -n 1 | python3 -c "import json, sys; print(json.load(sys.stdin)['$2'])"; }
near() { python3 -c "import sys; a, b, r = map(float, sys.argv[1:]); sys.exit(abs(a / b - 1) > r)" "$1" "$2" "$3"; }
code=$(status POST "/volume?format=iges" --data-binary @"$MS")
area=$(python3 -c "import json; print(json.load(open('$T/body'))['area_mm2'])" 2>/dev/null)
vol=$(python3 -c "import json; print(json.load(open('$T/body'))['volume_mm3'])" 2>/dev/null)
oa=$(occt "$MS" area_mm2); ov=$(occt "$MS" volume_mm3)
check "mug_solid.igs: closed; area $area mm² within 0.1 % of OCCT's $oa" '[ "$code" = 200 ] && grep -q "\"closed\":true" "$T/body" && near "$area" "$oa" 1e-3'
check "mug_solid.igs: volume $vol mm³ within 0.1 % of OCCT's $ov (the divergence theorem over the trimmed domains)" 'near "$vol" "$ov" 1e-3'
cp "$T/body" "$T/mug.json"
faces=$("$OCCT" "$MS" | tail -n 1 | python3 -c "
import json, sys
ours = json.load(open(sys.argv[1]))['surface_figures']; theirs = json.load(sys.stdin)['face_areas_mm2']
print(len(ours) == len(theirs) and all(abs(a['area_mm2'] / b - 1) < 1e-3 and a['entity'].startswith('D') for a, b in zip(ours, theirs)))" "$T/mug.json")
check "mug_solid.igs: each surface's area (surface_figures, by entity) within 0.1 % of OCCT's face" '[ "$faces" = True ]'
code=$(status POST /volume -H 'Content-Type: model/iges' --data-binary @"$D/mug.iges")
check "mug.iges (an open sheet): 422 naming a surface's entity and its 406 name, saying where it is open" '[ "$code" = 422 ] && is_problem 422 && grep -q "\"pointer\":\"D[0-9]*\"" "$T/body" && grep -q "do not bound a closed solid" "$T/body" && grep -q "(Body1[24])" "$T/body"'
while read -r name want; do
    code=$(status POST "/volume?format=iges" --data-binary @"$T/$name.igs")
    got=$(sed -n 's/.*their area is \([0-9.e+]*\) mm.*/\1/p' "$T/body")
    oa=$(occt "$T/$name.igs" area_mm2)
    check "$name: area $got mm² within 0.01 % of the exact $want (OCCT $oa)" '[ "$code" = 422 ] && near "$got" "$want" 1e-4 && near "$oa" "$want" 1e-4'
done <"$T/areas"

# ---- what a user sends: media types, colour ---------------------------------------------------------
code=$(status POST "/render?width=64&height=64" -H 'Content-Type: model/iges' --data-binary @"$MS")
check "Content-Type model/iges, no ?format: 200 PNG" '[ "$code" = 200 ] && header Content-Type | grep -q image/png'
code=$(status POST "/render?width=64&height=64" --data-binary @"$MS")
check "curl's default form type: the IGES file sniffed, 200" '[ "$code" = 200 ]'
code=$(status POST "/render?width=64&height=64&eye=60,70,330&target=60,70,30&up=0,1,0&fov=30&samples=1" --data-binary @"$T/plate_square.igs")
cp "$T/body" "$T/red.png"
red=$(python3 -c "
import sys; sys.path.insert(0, 'tests/tools'); import png_read
w, h, r = png_read.read('$T/red.png'); p = r[20][32]  # 30 mm above the centre: between the hole and the edge
print(int(p[0] > 2 * p[1] and p[0] > 2 * p[2]))")
check "a 314 colour reaches the picture (the plate is red)" '[ "$code" = 200 ] && [ "$red" = 1 ]'

# ---- the clients ----------------------------------------------------------------------------------
SURFD_URL="$URL" ./build/surfctl render "$MS" -o "$T/c.png" --width 96 --height 96 --eye 250,-300,220 --target 0,0,40
check "surfctl render PART.igs (model/iges by the extension)" '[ $? -eq 0 ] && [ "$(head -c 4 "$T/c.png" | od -An -tx1 | tr -d " \n")" = 89504e47 ]'
SURFD_URL="$URL" ./build/surfctl volume "$MS" >"$T/v.json"
check "surfctl volume PART.igs: the figures, closed" '[ $? -eq 0 ] && grep -q "\"kind\":\"trimmed surfaces\"" "$T/v.json" && grep -q "\"closed\":true" "$T/v.json"'
got=$(python3 -c "
import sys; sys.path.insert(0, 'client/python'); import surfd
print(surfd.Client('$URL').volume('$MS')['volume_mm3'])")
check "the Python client's volume() of PART.igs: $got mm³" '[ "$(echo "$got" | cut -d. -f1)" = "$(echo "$vol" | cut -d. -f1)" ]'

# ---- broken files ----------------------------------------------------------------------------------
# bad NAME STATUS POINTER_PATTERN: the mutated file $T/bad.igs refused so
bad_file() {
    name=$1 want=$2 ptr=$3
    code=$(status POST "/render?format=iges&width=32&height=32" --data-binary @"$T/bad.igs")
    [ -n "${IGES_VERBOSE:-}" ] && echo "$name: $code $(cat "$T/body")"
    check "$name: $want at $ptr" '[ "$code" = "$want" ] && is_problem "$want" && grep -q "\"pointer\":\"$ptr" "$T/body"'
}
mutate() { # mutate PYTHON: edits the entities of plate_hole (ents) before writing $T/bad.igs
    python3 -c "
import sys; sys.path.insert(0, 'tests/tools'); import iges_write as w
ents = w.plate_hole()
$1
w.write(sys.argv[1], ents)" "$T/bad.igs"
}
mutate "ents[3]['status'] = 10000"
bad_file "the trimmed surface physically dependent (01: drawn through a parent, and it has none): nothing to draw" 422 'D7"'
check "... saying why" 'grep -q "physically dependent with no parent drawing it" "$T/body"'
mutate "ents[3]['status'] = 1000000"
bad_file "the trimmed surface blanked: nothing to draw, at the surface" 422 'D7"'
mutate "ents = [ents[1]]"
bad_file "no surface at all: nothing to draw, at the Directory" 422 'D1"'
mutate "ents = w.plate_group(); ents[4]['params'][1] = ('D', 9)"
code=$(status POST "/render?format=iges&width=32&height=32" --data-binary @"$T/bad.igs")
check "a 402 group's member pointing at nothing: left out (a group only names), the part drawn" '[ "$code" = 200 ]'
code=$(status POST "/volume?format=iges" --data-binary @"$T/plate_group.igs")
check "a 402 group's member without a name of its own has the group's (its 406: Plate7)" '[ "$code" = 422 ] && grep -q "surface (Plate7)" "$T/body"'

mutate "ents[0]['params'][12] = 0.5"
bad_file "a bad final knot (0, 0, 1, 0.5)" 422 "D1"
mutate "ents[0]['params'] = ents[0]['params'][:-4]"
bad_file "missing U/V ranges" 422 "D1"
mutate "ents[1] = w.line((0.2, 0.2, 0), (0.8, 0.3, 0))"
bad_file "a loop of one line (encloses nothing)" 422 "D5"
mutate "ents[1] = {'type': 100, 'status': 10500, 'params': [0, 0.5, 0.5, 0.75, 0.5, 0.5, 0.75]}"
bad_file "an unclosed loop (a quarter circle for a hole)" 422 "D5"
mutate "ents[3]['params'][0] = 99"
bad_file "a surface pointer to nothing" 422 "D7"
mutate "ents[2]['params'][2] = ('D', 3)"
bad_file "a trim curve that is no curve (the 144 itself)" 422 "D7"
mutate "ents[0]['params'][:4] = [3000, 3000, 1, 1]"
bad_file "a surface of 3001 x 3001 points (over the cap)" 422 "D1"
mutate "ents[0]['params'][2] = 30"
bad_file "degree 30 (over the cap of 24)" 422 "D1"
mutate "ents.append({'type': 102, 'status': 10500, 'params': [1, ('D', 4)]}); ents[2]['params'][2] = ('D', 4)"
bad_file "a composite curve made of itself" 422 "D9"
python3 -c "import sys; print(open(sys.argv[1]).read().replace('S      1', 'C      1', 1), end='')" "$T/plate_hole.igs" >"$T/bad.igs"
bad_file "compressed IGES (C in column 73)" 400 "line 1"
head -c 2000 "$MS" | cut -c1-60 >"$T/bad.igs"
bad_file "lines cut short (no section column)" 400 "line "
python3 -c "import sys; l = open(sys.argv[1]).read().split('\n'); i = [k for k, s in enumerate(l) if s[72:73] == 'D'][0]; del l[i]; print('\n'.join(l), end='')" "$T/plate_hole.igs" >"$T/bad.igs"
bad_file "a directory of an odd number of lines: at its last" 400 'D7"'
python3 -c "import sys; l = open(sys.argv[1]).read().split('\n'); print('\n'.join(s for s in l if s[72:73] != 'P'), end='')" "$T/plate_hole.igs" >"$T/bad.igs"
bad_file "no Parameter section: at P" 400 'P"'

python3 -c "import sys; sys.path.insert(0, 'tests/tools'); import iges_write as w; w.write(sys.argv[1], w.plate_hole(), unit=3, unit_name='XX')" "$T/bad.igs"
bad_file "unit flag 3 naming no unit" 422 "G14"
code=$(status POST "/volume?format=iges" --data-binary @"$T/bad.igs")
check "/volume refuses the same way" '[ "$code" = 422 ] && grep -q "\"pointer\":\"G14\"" "$T/body"'
mutate "ents[1] = w.arc(5, 5, 0.1); ents[3]['params'][1:3] = [1, 0]; ents[3]['params'][3:] = [('D', 2)]"
bad_file "an outer loop wholly off the surface's domain (nothing left to draw)" 422 "D7"
code=$(status POST "/volume?format=iges" --data-binary @"$T/bad.igs")
check "... and nothing left to measure: /volume 422 at D7" '[ "$code" = 422 ] && grep -q "\"pointer\":\"D7" "$T/body"'
code=$(status POST "/volume?format=step" --data-binary @"$MS")
check "/volume?format=step: 400 at ?format (no silent fall to the contour reader)" '[ "$code" = 400 ] && grep -q "\"pointer\":\"?format\"" "$T/body"'
check "the daemon is up after every broken file" 'alive'
finish
