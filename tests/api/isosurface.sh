#!/bin/sh
# POST /isosurface through HTTP (issue 14): the shared CT crop as raw samples, as NRRD (raw and
# gzip) and as MetaImage, each a closed mesh model with VTK's figures; the mesh downloaded and
# checked for closure; every kind of bad input with its status and pointer.
. "$(dirname "$0")/lib.inc"

V="${SURFD_DATA:-../shared/data}/volumes"
CT="$V/ct_head_crop64_int16.raw"
[ -f "$CT" ] || { bad "../shared/data/volumes not found"; checks_done; exit 1; }
RAW='Content-Type: application/octet-stream'
Q="iso=226.5&dims=64,64,64&type=int16&spacing=0.9570312,0.9570312,1.5"
start_daemon "$T/d" --threads 2 || exit 1

field() { python3 -c "import json,sys; print(json.load(open(sys.argv[1])).get(sys.argv[2]))" "$T/body" "$1"; }
# the figures VTK's Flying Edges gives for the crop at 226.5, padded: 34 996 triangles, 57 560.5 mm^3
vtk_like() {
    python3 -c "
import json, sys
m = json.load(open(sys.argv[1]))
ok = (m['source'] == 'isosurface' and abs(m['triangles'] / 34996 - 1) < 0.02 and abs(m['volume_mm3'] / 57560.5 - 1) < 0.002
      and m['boundary_edges'] == 0 and m['nonmanifold_edges'] == 0 and m['euler_characteristic'] % 2 == 0
      and m['timings_ms']['extract'] > 0 and m['grid']['dims'] == [64, 64, 64])
sys.exit(0 if ok else 1)" "$T/body"
}

code=$(status POST "/isosurface?$Q&name=crop" -H "$RAW" --data-binary @"$CT")
id=$(field id)
check "raw samples: 201, Location, the mesh model" '[ "$code" = 201 ] && [ "$(header Location)" = "/models/$id" ] && [ "$(field name)" = crop ]'
check "... closed, with VTK's triangle count (2 %) and volume (0.2 %)" 'vtk_like'
check "... listed among the models" '[ "$(status GET /models)" = 200 ] && grep -q "$id" "$T/body"'
code=$(status GET "/models/$id/mesh?format=stl")
cp "$T/body" "$T/crop.stl"
check "its STL: closed, every edge twice, once each way" '[ "$code" = 200 ] && python3 tests/tools/stl_check.py "$T/crop.stl" 57529.6 >/dev/null'
vtk_same() { # vtk_same FILE: VTK reads it with the model's triangle count, its normals, closed, and its volume (0.01 %)
    /usr/bin/python3 tests/tools/vtk_check.py "$1" >"$T/vtk.json" && python3 -c "
import json, sys
v = json.load(open(sys.argv[1])); m = json.load(open(sys.argv[2]))
sys.exit(0 if v['triangles'] == m['triangles'] and v['normals'] and v['boundary_edges'] == 0
         and abs(v['volume'] / m['volume_mm3'] - 1) < 1e-4 else 1)" "$T/vtk.json" "$T/model.json"
}
cp "$T/body" "$T/model.json" 2>/dev/null; status GET "/models/$id" >/dev/null; cp "$T/body" "$T/model.json"
code=$(status GET "/models/$id/mesh?format=vtp"); cp "$T/body" "$T/crop.vtp"
check "its VTP (VTK XML PolyData): read by VTK with the model's triangles, normals and volume, closed, named for download" '[ "$code" = 200 ] && [ "$(header Content-Type)" = model/vnd.vtk.vtp+xml ] && header Content-Disposition | grep -q "filename=\"$id.vtp\"" && vtk_same "$T/crop.vtp"'
code=$(status GET "/models/$id/mesh?format=vtk"); cp "$T/body" "$T/crop.vtk"
check "... and legacy VTK the same" '[ "$code" = 200 ] && vtk_same "$T/crop.vtk"'
check "... a format it does not write: 422 at ?format naming the eight" '[ "$(status GET "/models/$id/mesh?format=off")" = 422 ] && grep -q "vtk, dicom-stl, seg or delta" "$T/body"'
check "... and PLY and OBJ" '[ "$(status GET "/models/$id/mesh?format=ply")" = 200 ] && head -c 3 "$T/body" | grep -q ply && [ "$(status GET "/models/$id/mesh?format=obj")" = 200 ] && grep -q "^f " "$T/body"'
check "its /patches: 422 (a mesh has none)" '[ "$(status GET "/models/$id/patches")" = 422 ] && is_problem 422'
code=$(status GET "/models/$id/render?width=320&height=240")
cp "$T/body" "$T/crop.png"
cover=$(python3 tests/tools/png_cover.py "$T/crop.png" 2>/dev/null)
check "its /render: a PNG of the skull (triangles beside no patch, normals from the gradient)" '[ "$code" = 200 ] && [ "$(header Content-Type)" = image/png ] && python3 -c "import sys; sys.exit(0 if float(sys.argv[1]) > 0.05 else 1)" "$cover"'
code=$(status POST "/render?width=160&height=120" -H 'Content-Type: application/json' --data-binary "{\"objects\":[{\"type\":\"model\",\"id\":\"$id\"},{\"type\":\"bezier\",\"degree\":[1,1],\"points\":[[0,0,0],[60,0,0],[0,60,0],[60,60,0]]}]}")
check "... in a scene beside a patch" '[ "$code" = 200 ] && [ "$(header Content-Type)" = image/png ]'
check "... with method map: 422 naming ?method (the map knows patches alone)" '[ "$(status GET "/models/$id/render?method=map")" = 422 ] && grep -q "?method" "$T/body"'

# the same samples as an attached NRRD (odd header length: unaligned samples), gzip NRRD, MetaImage
python3 - "$CT" "$T" <<'EOF'
import gzip, sys
raw = open(sys.argv[1], "rb").read()
h = "NRRD0004\ntype: int16\ndimension: 3\nsizes: 64 64 64\nspace directions: (0.9570312,0,0) (0,0.9570312,0) (0,0,1.5)\nendian: little\n"
open(sys.argv[2] + "/ct.nrrd", "wb").write((h + "encoding: raw\n\n").encode() + raw)
open(sys.argv[2] + "/ct_gz.nrrd", "wb").write((h + "encoding: gzip\n\n").encode() + gzip.compress(raw))
m = ("ObjectType = Image\nNDims = 3\nBinaryData = True\nBinaryDataByteOrderMSB = False\nCompressedData = False\n"
     "Offset = 0 0 0\nElementSpacing = 0.9570312 0.9570312 1.5\nDimSize = 64 64 64\nElementType = MET_SHORT\n"
     "ElementDataFile = LOCAL\n")
open(sys.argv[2] + "/ct.mha", "wb").write(m.encode() + raw)
EOF
code=$(status POST "/isosurface?iso=226.5" -H 'Content-Type: application/x-nrrd' --data-binary @"$T/ct.nrrd")
check "NRRD (raw encoding): the same mesh" '[ "$code" = 201 ] && vtk_like'
code=$(status POST "/isosurface?iso=226.5" -H 'Content-Type: application/x-nrrd' --data-binary @"$T/ct_gz.nrrd")
check "NRRD (gzip)" '[ "$code" = 201 ] && vtk_like'
code=$(status POST "/isosurface?iso=226.5" -H 'Content-Type: application/x-metaimage' --data-binary @"$T/ct.mha")
check "MetaImage (.mha)" '[ "$code" = 201 ] && vtk_like'
code=$(status POST "/isosurface?iso=226.5" --data-binary @"$T/ct.nrrd")
check "a body without its type is sniffed" '[ "$code" = 201 ] && vtk_like'
code=$(status POST "/isosurface?$Q&closed=false" -H "$RAW" --data-binary @"$CT")
check "closed=false: open where the surface meets the border" '[ "$code" = 201 ] && [ "$(field boundary_edges)" -gt 0 ] && [ "$(field nonmanifold_edges)" = 0 ]'

# ---- a DICOM series as multipart/form-data, posted in reverse: sorted by position, rescaled to HU ----
DD="$V/dicom_ct_head_64x64x27"
parts=""; for f in $(ls "$DD" | sort -r); do parts="$parts -F slice=@$DD/$f"; done
# shellcheck disable=SC2086
code=$(status POST "/isosurface?iso=226.5" $parts)
check "a DICOM series (parts in reverse order): 201, closed" '[ "$code" = 201 ] && [ "$(field boundary_edges)" = 0 ] && [ "$(field nonmanifold_edges)" = 0 ]'
cp "$T/body" "$T/series.json"
# the README: the series is ct[::4, ::4, ::4] of the full CT, in HU: the same mesh from those raw samples
python3 - "$V/ct_head_256x256x108_int16.raw" "$T/sub.raw" <<'EOF2'
import array, sys
a = array.array("h"); a.frombytes(open(sys.argv[1], "rb").read())
out = array.array("h", (a[x + 256 * (y + 256 * z)] for z in range(0, 108, 4) for y in range(0, 256, 4) for x in range(0, 256, 4)))
open(sys.argv[2], "wb").write(out.tobytes())
EOF2
code=$(status POST "/isosurface?iso=226.5&dims=64,64,27&type=int16&spacing=3.828125,3.828125,6" -H "$RAW" --data-binary @"$T/sub.raw")
same_mesh() { python3 -c "
import json, sys
a, b = json.load(open(sys.argv[1])), json.load(open(sys.argv[2]))
sys.exit(0 if a['triangles'] == b['triangles'] and abs(a['volume_mm3'] - b['volume_mm3']) < 1e-6 * b['volume_mm3'] and a['grid']['spacing'] == b['grid']['spacing'] else 1)" "$1" "$2"; }
check "... the same mesh as its samples posted raw (sorting, rescale and spacing right)" '[ "$code" = 201 ] && same_mesh "$T/series.json" "$T/body"'
$S isosurface "$DD" --iso 226.5 >"$T/offline.json" 2>/dev/null
check "... and surfd isosurface DIR offline gives it too" 'same_mesh "$T/offline.json" "$T/series.json"'
P="$V/dicom_pydicom_ct5n_16x16x5"
parts=""; for f in "$P"/*.dcm; do parts="$parts -F slice=@$f"; done
# shellcheck disable=SC2086
code=$(status POST "/isosurface?iso=-500" $parts)
check "a scanner's series whose file names are not in position order: sorted, 2.5 mm apart" '[ "$code" = 201 ] && python3 -c "
import json, sys; g = json.load(open(sys.argv[1]))[\"grid\"]; sys.exit(0 if g[\"dims\"] == [16, 16, 5] and abs(g[\"spacing\"][2] - 2.5) < 1e-6 else 1)" "$T/body"'
parts=""; for f in $(ls "$DD" | grep -v IM0014); do parts="$parts -F slice=@$DD/$f"; done
# shellcheck disable=SC2086
code=$(status POST "/isosurface?iso=226.5" $parts)
check "a series with a slice missing: 422 naming the part after the gap" '[ "$code" = 422 ] && grep -q "\"pointer\":\"/parts/[0-9]*\"" "$T/body" && grep -q "missing" "$T/body"'
# shellcheck disable=SC2086
code=$(status POST "/isosurface?iso=226.5" -F "slice=@$DD/IM0001.dcm" -F "slice=@$DD/IM0002.dcm" -F "slice=@$P/2062.dcm")
check "a series of mixed sizes: 422 naming the odd part" '[ "$code" = 422 ] && grep -q "\"pointer\":\"/parts/2\"" "$T/body" && grep -q "another size" "$T/body"'
# shellcheck disable=SC2086
code=$(status POST "/isosurface?iso=226.5" -F "slice=@$DD/IM0001.dcm" -F "slice=@$CT")
check "a part that is not DICOM: 400 naming it" '[ "$code" = 400 ] && grep -q "\"pointer\":\"/parts/1\"" "$T/body"'
code=$(status POST "/isosurface?iso=226.5" -F "slice=@$DD/IM0001.dcm")
check "one slice is not a series: 422" '[ "$code" = 422 ] && is_problem 422'

# ---- bad input ----
head -c 1000 "$CT" >"$T/short.raw"
code=$(status POST "/isosurface?$Q" -H "$RAW" --data-binary @"$T/short.raw")
check "a body whose length is not dims x type: 422 at ?dims" '[ "$code" = 422 ] && grep -q "\"pointer\":\"?dims\"" "$T/body"'
code=$(status POST "/isosurface?dims=64,64,64&type=int16" -H "$RAW" --data-binary @"$CT")
check "no iso: 422 at ?iso" '[ "$code" = 422 ] && grep -q "\"pointer\":\"?iso\"" "$T/body"'
code=$(status POST "/isosurface?iso=1&dims=64,64,64&type=int64" -H "$RAW" --data-binary @"$CT")
check "an unknown type: 422 at ?type" '[ "$code" = 422 ] && grep -q "\"pointer\":\"?type\"" "$T/body"'
code=$(status POST "/isosurface?iso=1&dims=4000000000,2,2&type=uint8" -H "$RAW" --data-binary @"$CT")
check "dims past the limits: 422 at ?dims" '[ "$code" = 422 ] && grep -q "\"pointer\":\"?dims\"" "$T/body"'
code=$(status POST "/isosurface?iso=1&dims=2000,2000,2000&type=uint8" -H "$RAW" --data-binary @"$CT")
check "dims whose product is over the sample limit: 422 at ?dims" '[ "$code" = 422 ] && grep -q "over the limit" "$T/body"'
code=$(status POST "/isosurface?$Q&spacing=inf,1,1" -H "$RAW" --data-binary @"$CT")
check "non-finite spacing: 422 at ?spacing" '[ "$code" = 422 ] && grep -q "\"pointer\":\"?spacing\"" "$T/body"'
python3 -c "import struct,sys; sys.stdout.buffer.write(struct.pack('<8f', 0, 1, 2, float('nan'), 4, 5, 6, 7))" >"$T/nan.raw"
code=$(status POST "/isosurface?iso=1&dims=2,2,2&type=float32" -H "$RAW" --data-binary @"$T/nan.raw")
check "a NaN sample: 422 naming it (refused, not taken as outside)" '[ "$code" = 422 ] && grep -q "sample (1, 1, 0)" "$T/body"'
printf 'NRRD0004\ntype: int16\nsizes: 64 64\n\n' >"$T/bad.nrrd"
code=$(status POST "/isosurface?iso=1" -H 'Content-Type: application/x-nrrd' --data-binary @"$T/bad.nrrd")
check "a garbage NRRD header: 422 naming its line" '[ "$code" = 422 ] && grep -q "header line 3" "$T/body"'
printf 'NRRD0004\ntype: int16\nsizes: 64 64 64\ndata file: ct.raw\n\n' >"$T/det.nrrd"
code=$(status POST "/isosurface?iso=1" -H 'Content-Type: application/x-nrrd' --data-binary @"$T/det.nrrd")
check "a detached NRRD header: 422 saying to attach the data" '[ "$code" = 422 ] && grep -q "attached" "$T/body"'
code=$(status POST "/isosurface?iso=1" -H 'Content-Type: image/png' --data-binary @"$CT")
check "a type it does not read: 415" '[ "$code" = 415 ] && is_problem 415'
code=$(status POST "/isosurface?$(echo "$Q" | sed 's/iso=226.5/iso=30000/')" -H "$RAW" --data-binary @"$CT")
check "an iso above every sample: 422 at ?iso (no empty model stored)" '[ "$code" = 422 ] && grep -q "\"pointer\":\"?iso\"" "$T/body"'
code=$(status POST "/isosurface?$Q&smooth=2" -H "$RAW" --data-binary @"$CT")
check "an option it does not take: 422 naming it" '[ "$code" = 422 ] && grep -q "\"pointer\":\"?smooth\"" "$T/body"'
code=$(status POST "/isosurface?$Q&levels=5" -H "$RAW" --data-binary @"$CT")
check "levels over 4: 422 at ?levels" '[ "$code" = 422 ] && grep -q "\"pointer\":\"?levels\"" "$T/body"'
code=$(status POST "/isosurface?$Q&levels=2&merge=faces" -H "$RAW" --data-binary @"$CT")
check "merge neither cells nor pieces: 422 at ?merge" '[ "$code" = 422 ] && grep -q "\"pointer\":\"?merge\"" "$T/body"'
code=$(status POST "/isosurface?$Q&levels=2&merge=pieces&features=sharp" -H "$RAW" --data-binary @"$CT")
check "merge=pieces with features=sharp: 422 at ?merge, the daemon still up" '[ "$code" = 422 ] && grep -q "\"pointer\":\"?merge\"" "$T/body" && [ "$(status GET /readyz)" = 200 ]'
{ printf 'NRRD0004\ntype: uint8\ndimension: 3\nsizes: 1024 1024 300\nencoding: gzip\n\n'; printf 'x' | gzip; } >"$T/huge.nrrd"
code=$(status POST "/isosurface?iso=1&levels=2" -H 'Content-Type: application/x-nrrd' --data-binary @"$T/huge.nrrd")
check "levels=2 on a volume over 2^28 samples: 422 at ?levels, before it is inflated" '[ "$code" = 422 ] && grep -q "\"pointer\":\"?levels\"" "$T/body"'
code=$(status POST "/isosurface?$Q&levels=2&max_error=-1" -H "$RAW" --data-binary @"$CT")
check "a negative max_error: 422 at ?max_error" '[ "$code" = 422 ] && grep -q "\"pointer\":\"?max_error\"" "$T/body"'
python3 - "$T/many.multipart" <<'EOF2'
import sys
part = b'--b\r\nContent-Disposition: form-data; name="s"\r\n\r\nx\r\n'
open(sys.argv[1], "wb").write(part * 10001 + b"--b--\r\n")
EOF2
code=$(status POST "/isosurface?iso=1" -H 'Content-Type: multipart/form-data; boundary=b' --data-binary @"$T/many.multipart")
check "a series of over 10 000 parts: 422 at the part past the cap" '[ "$code" = 422 ] && grep -q "\"pointer\":\"/parts/10000\"" "$T/body"'
check "the daemon is up after all of it" 'alive'

# ---- the adaptive hierarchy (issue 15): coarser cells where the surface allows, still closed ----
code=$(status POST "/isosurface?$Q&levels=3&max_error=1" -H "$RAW" --data-binary @"$CT")
aid=$(field id) avol=$(field volume_mm3)
check "levels=3&max_error=1: 201, closed, fewer triangles, cells of three levels" '[ "$code" = 201 ] && python3 -c "
import json, sys
m = json.load(open(sys.argv[1]))
ok = (m[\"levels\"] == 3 and m[\"max_error\"] == 1 and m[\"boundary_edges\"] == 0 and m[\"nonmanifold_edges\"] == 0
      and m[\"triangles\"] < 34996 * 0.8 and all(c > 0 for c in m[\"cells_by_level\"]) and m[\"max_error_estimate\"] <= 1
      and abs(m[\"volume_mm3\"] / 57560.5 - 1) < 0.05)
sys.exit(0 if ok else 1)" "$T/body"'
check "... its STL closed too" '[ "$(status GET "/models/$aid/mesh?format=stl")" = 200 ] && cp "$T/body" "$T/adapt.stl" && python3 tests/tools/stl_check.py "$T/adapt.stl" "$avol" >/dev/null'

# ---- FRep objects (issue 15): the API.md example, a sphere, and every kind of bad tree ----
cat >"$T/bracket.json" <<'EOF2'
{"name": "bracket", "bounds": [[-2, -2, -2], [2, 2, 2]], "cell": 0.02, "alpha": 0,
 "frep": {"subtract": [
   {"union": [{"box": {"min": [-1, -1, -1], "max": [1, 1, 1]}},
              {"cylinder": {"base": [0, 0, -1.5], "axis": [0, 0, 1], "radius": 0.5, "length": 3}}]},
   {"transform": {"translate": [1, 1, 1], "rotate_deg": [0, 0, 45], "scale": [1, 1, 1],
                  "object": {"sphere": {"center": [0, 0, 0], "radius": 0.6}}}}]}}
EOF2
code=$(status POST /isosurface -H 'Content-Type: application/json' --data-binary @"$T/bracket.json")
fid=$(field id)
# the box, the cylinder's two ends out of it, less the ball's octant in the box's corner
check "the API.md bracket: 201, one closed shell, its volume within 0.1 %" '[ "$code" = 201 ] && python3 -c "
import json, math, sys
m = json.load(open(sys.argv[1]))
want = 8 + math.pi * 0.25 * 1 - 4 / 3 * math.pi * 0.6 ** 3 / 8
ok = (m[\"source\"] == \"frep\" and m[\"name\"] == \"bracket\" and m[\"boundary_edges\"] == 0 and m[\"nonmanifold_edges\"] == 0
      and m[\"components\"] == 1 and m[\"euler_characteristic\"] == 2 and abs(m[\"volume_mm3\"] / want - 1) < 1e-3
      and m[\"grid\"][\"dims\"] == [201, 201, 201] and m[\"timings_ms\"][\"sample\"] > 0)
sys.exit(0 if ok else 1)" "$T/body"'
check "... rendered like any model" '[ "$(status GET "/models/$fid/render?width=96&height=96")" = 200 ] && [ "$(header Content-Type)" = image/png ]'
code=$(status POST /isosurface --data-binary '{"bounds": [[-1.2, -1.2, -1.2], [1.2, 1.2, 1.2]], "cell": 0.02, "frep": {"transform": {"translate": [5, 0, 0], "object": {"sphere": {"center": [-5, 0, 0], "radius": 1}}}}}')
sid=$(field id)
check "a sphere (sniffed JSON, moved back by a transform): its volume within 0.05 %" '[ "$code" = 201 ] && python3 -c "
import json, math, sys
m = json.load(open(sys.argv[1]))
sys.exit(0 if abs(m[\"volume_mm3\"] / (4 / 3 * math.pi) - 1) < 5e-4 and abs(m[\"area_mm2\"] / (4 * math.pi) - 1) < 1e-3 else 1)" "$T/body"'
check "... its STL closed, every edge twice, once each way" '[ "$(status GET "/models/$sid/mesh?format=stl")" = 200 ] && cp "$T/body" "$T/sphere.stl" && python3 tests/tools/stl_check.py "$T/sphere.stl" 4.18879 >/dev/null'
# features=sharp (seed 002's feature points): the bracket's box edges and the curves where the
# cylinder and the ball meet it, on a coarser grid; its volume nearer than without
sed 's/"cell": 0.02/"cell": 0.05/' "$T/bracket.json" >"$T/bracket05.json"
code=$(status POST "/isosurface?features=sharp" -H 'Content-Type: application/json' --data-binary @"$T/bracket05.json")
cp "$T/body" "$T/sharp.json"
code2=$(status POST /isosurface -H 'Content-Type: application/json' --data-binary @"$T/bracket05.json")
check "features=sharp: 201, closed, one shell, feature and face points, its volume within 0.05 % and nearer than without" '[ "$code" = 201 ] && [ "$code2" = 201 ] && python3 -c "
import json, math, sys
m, plain = json.load(open(sys.argv[1])), json.load(open(sys.argv[2]))
want = 8 + math.pi * 0.25 * 1 - 4 / 3 * math.pi * 0.6 ** 3 / 8
err = lambda r: abs(r[\"volume_mm3\"] / want - 1)
ok = (m[\"features\"] == \"sharp\" and plain[\"features\"] == \"none\" and m[\"feature_points\"] > 0 and m[\"face_points\"] > 0
      and m[\"boundary_edges\"] == 0 and m[\"nonmanifold_edges\"] == 0 and m[\"components\"] == 1 and m[\"euler_characteristic\"] == 2
      and err(m) < 5e-4 and err(m) < err(plain) / 2)
sys.exit(0 if ok else 1)" "$T/sharp.json" "$T/body"'
code=$(status POST "/isosurface?$Q&features=sharp&levels=2" -H "$RAW" --data-binary @"$CT")
check "features=sharp&levels=2 on the CT (normals from the samples): 201, closed" '[ "$code" = 201 ] && python3 -c "
import json, sys
m = json.load(open(sys.argv[1]))
sys.exit(0 if m[\"features\"] == \"sharp\" and m[\"boundary_edges\"] == 0 and m[\"nonmanifold_edges\"] == 0 and m[\"feature_points\"] > 0 else 1)" "$T/body"'
code=$(status POST "/isosurface?features=round" -H 'Content-Type: application/json' --data-binary @"$T/bracket05.json")
check "features=round: 422 at ?features" '[ "$code" = 422 ] && grep -q "\"pointer\":\"?features\"" "$T/body"'
code=$(status POST "/isosurface?iso=1&features=sharp" -H 'Content-Type: application/x-nrrd' --data-binary @"$T/huge.nrrd")
check "features=sharp on a volume over 2^28 samples: 422 at ?features, before it is inflated" '[ "$code" = 422 ] && grep -q "\"pointer\":\"?features\"" "$T/body"'
code=$(status POST "/isosurface?levels=3&max_error=0.01" -H 'Content-Type: application/json' --data-binary @"$T/bracket.json")
check "the bracket with levels=3&max_error=0.01: closed, one shell, fewer triangles, its volume within 0.2 %" '[ "$code" = 201 ] && python3 -c "
import json, math, sys
m = json.load(open(sys.argv[1]))
want = 8 + math.pi * 0.25 * 1 - 4 / 3 * math.pi * 0.6 ** 3 / 8
ok = (m[\"boundary_edges\"] == 0 and m[\"nonmanifold_edges\"] == 0 and m[\"components\"] == 1 and m[\"triangles\"] < 137272 / 2
      and abs(m[\"volume_mm3\"] / want - 1) < 2e-3)
sys.exit(0 if ok else 1)" "$T/body"'
frep_bad() { # body, pointer
    code=$(status POST /isosurface -H 'Content-Type: application/json' --data-binary "{\"bounds\": [[0, 0, 0], [1, 1, 1]], \"cell\": 0.1, \"frep\": $1}")
    [ "$code" = 422 ] && is_problem 422 && grep -q "\"pointer\":\"$2\"" "$T/body"
}
SPH='{"sphere": {"center": [0, 0, 0], "radius": 1}}'
check "an unknown primitive: 422 at it" 'frep_bad "{\"subtract\": [$SPH, {\"pyramid\": {}}]}" /frep/subtract/1/pyramid'
check "a negative radius: 422 at it" 'frep_bad "{\"sphere\": {\"center\": [0, 0, 0], \"radius\": -1}}" /frep/sphere/radius'
check "alpha out of [0, 1]: 422 at it" 'frep_bad "{\"union\": [$SPH, $SPH], \"alpha\": 2}" /frep/alpha'
check "a misspelt member: 422 at it" 'frep_bad "{\"sphere\": {\"center\": [0, 0, 0], \"raduis\": 1}}" /frep/sphere/raduis'
deep=$SPH; for _ in $(seq 70); do deep="{\"offset\": {\"distance\": 0, \"object\": $deep}}"; done
check "a tree over 64 levels deep: 422" 'frep_bad "$deep" "/frep\(/offset/object\)*" && grep -q "levels deep" "$T/body"'
code=$(status POST /isosurface -H 'Content-Type: application/json' --data-binary "{\"bounds\": [[0, 0, 0], [10, 10, 10]], \"cell\": 0.001, \"frep\": $SPH}")
check "a grid over the sample limit: 422 at /cell, before any sample" '[ "$code" = 422 ] && grep -q "\"pointer\":\"/cell\"" "$T/body"'
code=$(status POST /isosurface -H 'Content-Type: application/json' --data-binary "{\"bounds\": [[0, 0, 0], [1, 1, 1]], \"cell\": 0.1, \"frep\": {\"sphere\": {\"center\": [5, 5, 5], \"radius\": 1}}}")
check "an object outside its bounds: 422 at /bounds (no empty model stored)" '[ "$code" = 422 ] && grep -q "\"pointer\":\"/bounds\"" "$T/body"'
code=$(status POST "/isosurface?dims=2,2,2" -H 'Content-Type: application/json' --data-binary "{\"bounds\": [[0, 0, 0], [1, 1, 1]], \"cell\": 0.1, \"frep\": $SPH}")
check "raw options on an FRep: 422 naming them" '[ "$code" = 422 ] && grep -q "\"pointer\":\"?dims\"" "$T/body"'
check "the daemon is up after them" 'alive'

# ---- a long one: progress by slabs, cancel between slabs, and kill -9 recovery from the stored upload ----
BIG="$V/ct_head_256x256x108_int16.raw"
cat "$BIG" "$BIG" "$BIG" "$BIG" >"$T/ct4.raw" # 256x256x432
QB="iso=226.5&dims=256,256,432&type=int16&spacing=0.9570312,0.9570312,1.5"
# (the adaptive hierarchy's phases: the plain extraction of it can be past its slabs before the 202)
code=$(status POST "/isosurface?$QB&levels=2" -H "$RAW" -H 'Prefer: respond-async' --data-binary @"$T/ct4.raw")
big=$(field id)
check "a 57 MB volume, async: 202" '[ "$code" = 202 ]'
wait_state "$big" running 60
seen=0
for _ in $(seq 200); do
    curl -s "$URL/jobs/$big" >"$T/j"
    p=$(python3 -c "import json,sys; print(json.load(open(sys.argv[1]))['progress'])" "$T/j")
    # (below 0.9: still in the slabs, not storing the mesh, where a cancel can come too late)
    python3 -c "import sys; sys.exit(0 if 0 < float(sys.argv[1]) < 0.9 else 1)" "$p" && { seen=1; break; }
    sleep 0.02
done
check "... its progress moves by slabs" '[ $seen = 1 ]'
check "... cancel while it runs: 202" '[ "$(status POST "/jobs/$big/cancel")" = 202 ]'
check "... and it stops between slabs" 'wait_state "$big" cancelled 30'
code=$(status POST "/isosurface?$QB" -H "$RAW" -H 'Prefer: respond-async' --data-binary @"$T/ct4.raw")
again=$(field id)
wait_state "$again" running 60
kill -9 "$PID"; wait "$PID" 2>/dev/null; PID=""
check "... killed mid-job, the upload stays in the data dir" '[ -s "$T/d/uploads/$again" ]'
start_daemon "$T/d" --threads 2 || exit 1
check "... and at the next start the job runs from it to the end" 'wait_state "$again" succeeded 240 && [ "$(status GET "/models/$again")" = 200 ] && [ "$(field boundary_edges)" = 0 ]'

# ---- max-volume: the cap of a streamed body, from Content-Length and, chunked, as it arrives ----
stop_daemon
start_daemon "$T/capped" --max-volume 100000 || exit 1
code=$(status POST "/isosurface?$Q" -H "$RAW" --data-binary @"$CT")
check "a volume over max-volume: 413 before it is read" '[ "$code" = 413 ] && grep -q "limit of 100000" "$T/body"'
code=$(status POST "/isosurface?$Q" -H "$RAW" -H 'Transfer-Encoding: chunked' --data-binary @"$CT")
check "... and chunked, once it passes the cap" '[ "$code" = 413 ] && is_problem 413'
check "... leaving no upload behind" '[ -z "$(ls "$T/capped/uploads" 2>/dev/null)" ]'
stop_daemon
start_daemon "$T/d" --threads 2 || exit 1

# ---- it survives a restart, and goes away when deleted ----
stop_daemon
start_daemon "$T/d" --threads 2 || exit 1
check "the model is kept across a restart" '[ "$(status GET "/models/$id")" = 200 ] && [ "$(field triangles)" -gt 30000 ]'
check "DELETE removes it" '[ "$(status DELETE "/models/$id")" = 204 ] && [ "$(status GET "/models/$id")" = 404 ]'
finish
