#!/bin/sh
# Black-box regression tests of issue 48's findings 1b, 5 and 6 (the DICOM half of 5 is in
# hostile_dicom.sh): extreme numbers in volumes answered 500 "out of memory", stored meshes of
# volume 0, or (a NRRD origin of 1e24) made GET /models/{id}/rtstruct write past its buffer; now
# every origin, spacing and iso is in api/ranges.h's ranges or a 422 names it. And the names of
# things: /volume takes every format name /render takes, and a contour set named "matrix_model"
# is a contour set. The inputs are written here (a ball of 8^3 uint8 samples).
. "$(dirname "$0")/lib.inc"

cat >"$T/gen.py" <<'EOF'
import sys
d = sys.argv[1]
ball = bytes(200 if (x - 3.5) ** 2 + (y - 3.5) ** 2 + (z - 3.5) ** 2 < 7 else 0
             for z in range(8) for y in range(8) for x in range(8))
def nrrd(name, origin="(0,0,0)", spacings="1 1 1"):
    h = "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 8 8 8\nspacings: %s\nspace origin: %s\nencoding: raw\n\n" % (spacings, origin)
    open("%s/%s.nrrd" % (d, name), "wb").write(h.encode() + ball)
def mha(name, offset="0 0 0", spacing="1 1 1"):
    h = ("ObjectType = Image\nNDims = 3\nDimSize = 8 8 8\nElementType = MET_UCHAR\nElementSpacing = %s\nOffset = %s\n"
         "ElementDataFile = LOCAL\n" % (spacing, offset))
    open("%s/%s.mha" % (d, name), "wb").write(h.encode() + ball)
open(d + "/ball.raw", "wb").write(ball)
nrrd("ok")
nrrd("near", origin="(-250,-250,1000)", spacings="0.5 0.5 0.001")
nrrd("o1e300", origin="(1e300,0,0)")
nrrd("o1e24", origin="(0,0,1e24)")
nrrd("s1e-300", spacings="1e-300 1e-300 1e-300")
mha("o1e300", offset="1e300 0 0")
mha("s1e-300", spacing="1 1e-300 1")
EOF
python3 "$T/gen.py" "$T" || { bad "the inputs could not be written"; checks_done; exit 1; }

start_daemon "$T/d" --threads 2 || exit 1
NRRD='Content-Type: application/x-nrrd'
MHA='Content-Type: application/x-metaimage'
RAW='Content-Type: application/octet-stream'
J='Content-Type: application/json'
RAWQ='dims=8,8,8&type=uint8'
names() { is_problem 422 && grep -q "\"pointer\":\"$1\"" "$T/body" && grep -q "$2" "$T/body"; }
volume() { python3 -c "import json,sys; print(json.load(open(sys.argv[1]))['volume_mm3'])" "$T/body" 2>/dev/null; }
positive() { python3 -c "import sys; sys.exit(0 if float(sys.argv[1]) > 0 else 1)" "${1:-0}" 2>/dev/null; }

code=$(status POST "/isosurface?iso=100" -H "$NRRD" --data-binary @"$T/ok.nrrd")
check "the ball as NRRD: 201 with a volume" '[ "$code" = 201 ] && positive "$(volume)"'
code=$(status POST "/isosurface?iso=100" -H "$NRRD" --data-binary @"$T/near.nrrd")
check "... 250 mm out with 1 um slices (in range, float32 holds them apart): 201 with a volume" '[ "$code" = 201 ] && positive "$(volume)"'

# ---- 5: origins, spacings and iso past their ranges: a 422 naming the field -------------------------
code=$(status POST "/isosurface?iso=100" -H "$NRRD" --data-binary @"$T/o1e300.nrrd")
check "NRRD space origin 1e300: 422 naming its header line (it answered 500 out of memory)" '[ "$code" = 422 ] && names "header line 6" "space origin"'
code=$(status POST "/isosurface?iso=100" -H "$MHA" --data-binary @"$T/o1e300.mha")
check "MetaImage Offset 1e300: 422 naming its header line (it answered 500)" '[ "$code" = 422 ] && names "header line 6" Offset'
code=$(status POST "/isosurface?iso=-1e308" -H "$NRRD" --data-binary @"$T/ok.nrrd")
check "iso=-1e308: 422 at ?iso (it answered 500)" '[ "$code" = 422 ] && names "?iso" "within 1e+30"'
code=$(status POST "/isosurface?iso=300" -H "$NRRD" --data-binary @"$T/ok.nrrd")
check "iso=300 of uint8 samples: 422 at ?iso, said before any work" '[ "$code" = 422 ] && names "?iso" "uint8"'
code=$(status POST "/isosurface?iso=100&$RAWQ&origin=1e9,0,0" -H "$RAW" --data-binary @"$T/ball.raw")
check "raw samples at origin 1e9 mm: 422 at ?origin (it stored a mesh of volume 0)" '[ "$code" = 422 ] && names "?origin" "within 1e+06 mm"'
code=$(status POST "/isosurface?iso=100&$RAWQ&origin=999000,0,0&spacing=0.001,1,1" -H "$RAW" --data-binary @"$T/ball.raw")
check "... 999 000 mm out with 1 um cells float32 cannot hold apart: 422 at ?spacing" '[ "$code" = 422 ] && names "?spacing" float32'
code=$(status POST "/isosurface?iso=100&$RAWQ&spacing=1e-300,1e-300,1e-300" -H "$RAW" --data-binary @"$T/ball.raw")
check "raw spacings of 1e-300 mm: 422 at ?spacing (it stored a mesh of volume 0)" '[ "$code" = 422 ] && names "?spacing" "0.001 to 10000 mm"'
code=$(status POST "/isosurface?iso=100" -H "$NRRD" --data-binary @"$T/s1e-300.nrrd")
check "NRRD spacings of 1e-300: 422 naming the header line" '[ "$code" = 422 ] && names "header line 5" spacings'
code=$(status POST "/isosurface?iso=100" -H "$MHA" --data-binary @"$T/s1e-300.mha")
check "MetaImage ElementSpacing 1e-300: 422 naming the header line" '[ "$code" = 422 ] && names "header line 5" ElementSpacing'
code=$(status POST "/isosurface?iso=100&$RAWQ&spacing=1e4,1,1&origin=990000,0,0" -H "$RAW" --data-binary @"$T/ball.raw")
check "a grid whose far corner is 1 060 000 mm out: 422" '[ "$code" = 422 ] && names "?spacing" "reaches"'
code=$(status POST /isosurface -H "$J" --data-binary '{"bounds": [[0, 0, 0], [0.01, 0.01, 0.01]], "cell": 0.0001, "frep": {"sphere": {"center": [0, 0, 0], "radius": 0.005}}}')
check "an FRep of 0.1 um cells: 422 at /cell" '[ "$code" = 422 ] && names /cell "0.001 to 10000 mm"'
code=$(status POST /isosurface -H "$J" --data-binary '{"bounds": [[-5e6, 0, 0], [1, 1, 1]], "cell": 0.5, "frep": {"sphere": {"center": [0, 0, 0], "radius": 0.5}}}')
check "an FRep whose bounds are 5e6 mm out: 422 at /bounds/0" '[ "$code" = 422 ] && names /bounds/0 "within 1e+06 mm"'

# ---- 1b: the RT Structure Set of a model 1e24 mm out ------------------------------------------------
code=$(status POST "/isosurface?iso=100" -H "$NRRD" --data-binary @"$T/o1e24.nrrd")
id=$(python3 -c "import json,sys; print(json.load(open(sys.argv[1])).get('id', ''))" "$T/body" 2>/dev/null)
check "NRRD space origin 1e24: 422 naming its header line (it was stored, and its RT Structure Set written past a buffer)" '[ "$code" = 422 ] && names "header line 6" "space origin"'
[ "$code" = 201 ] && [ -n "$id" ] && rt=$(status GET "/models/$id/rtstruct" -m 30)
check "the daemon is up after it" 'alive'
alive || start_daemon "$T/d2" --threads 2 || exit 1  # (what follows checked on its own)

# ---- 6: format names -----------------------------------------------------------------------------
code=$(status POST "/volume?format=vrml" --data-binary @"$D/duck1.nurbs")
vrml=$(volume)
code=$(status POST "/volume?format=wrl" --data-binary @"$D/duck1.nurbs")
check "/volume?format=wrl: the name /render takes, the duck's volume as ?format=vrml (it was 400)" '[ "$code" = 200 ] && [ -n "$vrml" ] && [ "$(volume)" = "$vrml" ]'
code=$(status POST "/render?format=wrl&width=32&height=32" --data-binary @"$D/duck1.nurbs")
check "... as /render?format=wrl" '[ "$code" = 200 ]'
SQ='[[0,0],[10,0],[10,10],[0,10]]'
code=$(status POST /model -H "$J" --data-binary "{\"name\": \"matrix_model\", \"slices\": [{\"z\": 0, \"points\": $SQ}, {\"z\": 1, \"points\": $SQ}]}")
check "a contour set named \"matrix_model\" is a contour set: 201 (it was taken for a matrix model, 422)" '[ "$code" = 201 ] && grep -q "\"name\":\"matrix_model\"" "$T/body"'
code=$(status POST /model -H "$J" --data-binary "{\"name\": \"objects\", \"slices\": [{\"z\": 0, \"points\": $SQ}, {\"z\": 1, \"points\": $SQ}]}")
check "... and one named \"objects\" is no scene: 201" '[ "$code" = 201 ]'
code=$(status POST "/matrix-model?iso=100&$RAWQ" -H "$RAW" --data-binary @"$T/ball.raw")
python3 -c "import json,sys; m = json.load(open(sys.argv[1])); print(json.dumps({'name': 'ball', 'matrix_model': m['matrix_model']}))" "$T/body" >"$T/matrix.json" 2>/dev/null
code=$(status POST /model -H "$J" --data-binary @"$T/matrix.json")
check "a matrix model (its top-level key, after another) is still one: 201" '[ "$code" = 201 ] && grep -q "\"source\":\"matrix\"" "$T/body"'
code=$(status POST /model -H "$J" --data-binary '{"name": "m", "matrix_model": {"size": [0, 1, 1]}}')
check "... and a bad one is refused as one: 422 at /matrix_model/size/0" '[ "$code" = 422 ] && names /matrix_model/size/0 "a size"'
finish
