#!/bin/sh
# A volume's samples for the page's slice views (issue 46): GET /models/{id}/volume answers an
# isosurface model's samples as one NRRD (the type as stored, space directions and origin in
# patient LPS), its edits applied; GET /series/{uid}/volume a stored series' (a CT: int16 HU) with
# the geometry GET /series/{uid} gives; a model is its owner's (another token's: 404), a model
# without samples 409, an unknown series 404, all problem+json (samples over max-volume: 422);
# GET /pacs lists the PACS configured by name, their addresses unsaid.
. "$(dirname "$0")/lib.inc"
V="${SURFD_DATA:-../shared/data}/volumes"
DD="$V/dicom_ct_head_64x64x27"
C="${SURFD_DATA:-../shared/data}/contours/synthetic_ellipsoid.json"
[ -d "$DD" ] && [ -f "$C" ] || { bad "../shared/data not found"; checks_done; exit 1; }
command -v storescu >/dev/null || { bad "no storescu (deploy/install-deps.sh installs dcmtk)"; checks_done; exit 1; }
DP=$(python3 -c "import socket; s = socket.socket(); s.bind(('127.0.0.1', 0)); print(s.getsockname()[1])")
echo "STORESCU 127.0.0.1 11112" >"$T/peers"
printf 'alice:alice-secret-token-1\nbob:bob-secret-token-22\n' >"$T/tokens"
chmod 600 "$T/tokens"
A="Authorization: Bearer alice-secret-token-1"
B="Authorization: Bearer bob-secret-token-22"
start_daemon "$T/d" --dicom-listen "$DP" --dicom-peers "$T/peers" --series-idle 1 --token-file "$T/tokens" \
    --pacs "orthanc=http://127.0.0.1:1/dicom-web" --pacs "scanner=dicom://SCANNER@127.0.0.1:1" --max-volume 1000000 || exit 1
field() { python3 -c "import json,sys; v = json.load(open(sys.argv[1])); [v := v[k] if not isinstance(v, list) else v[int(k)] for k in sys.argv[2:]]; print(v)" "$T/body" "$@"; }
# nrrd FILE: the header's fields and the samples' count and range as JSON (python reads it as the page does)
nrrd() {
    python3 - "$1" <<'EOF'
import json, struct, sys
b = open(sys.argv[1], "rb").read()
end = b.index(b"\n\n")
f = {}
for line in b[:end].decode().split("\n")[1:]:
    if ":" in line and not line.startswith("#"):
        k, v = line.split(":", 1)
        f[k.strip()] = v.strip()
dims = [int(x) for x in f["sizes"].split()]
n = dims[0] * dims[1] * dims[2]
code = {"int16": "h", "uint8": "B", "uint16": "H", "float": "f"}[f["type"]]
data = struct.unpack("<%d%s" % (n, code), b[end + 2:end + 2 + n * struct.calcsize(code)])
dirs = [[float(x) for x in v.strip("() ").split(",")] for v in f["space directions"].split(") (")]
print(json.dumps({"type": f["type"], "dims": dims, "space": f["space"], "dirs": dirs,
                  "origin": [float(x) for x in f["space origin"].strip("()").split(",")],
                  "rest": len(b) - end - 2 - n * struct.calcsize(code), "lo": min(data), "hi": max(data),
                  "at": data[32 + 64 * (32 + 64 * 32)] if n == 64 ** 3 else None}))
EOF
}
val() { python3 -c "import json,sys; v = json.load(open(sys.argv[1])); [v := v[k] if not isinstance(v, list) else v[int(k)] for k in sys.argv[2:]]; print(v)" "$T/nrrd.json" "$@"; }

# ---- a model's samples ----
code=$(status POST "/isosurface?iso=226.5" -H "$A" -F header=@"$V/ct_head_crop64_int16.mhd" -F data=@"$V/ct_head_crop64_int16.raw")
ID=$(field id)
code=$(status GET "/models/$ID/volume" -H "$A")
nrrd "$T/body" >"$T/nrrd.json"
check "GET /models/{id}/volume: 200, application/x-nrrd" '[ "$code" = 200 ] && header Content-Type | grep -q "application/x-nrrd"'
check "... int16 samples 64 x 64 x 64, nothing after them, in patient LPS" \
    '[ "$(val type)" = int16 ] && [ "$(val dims)" = "[64, 64, 64]" ] && [ "$(val rest)" = 0 ] && [ "$(val space)" = left-posterior-superior ]'
check "... its spacing and origin as the MetaImage gives them" \
    '[ "$(val dirs)" = "[[0.957031, 0.0, 0.0], [0.0, 0.957031, 0.0], [0.0, 0.0, 1.5]]" ] && [ "$(val origin)" = "[91.875, 0.0, 33.0]" ]'
check "... the samples the .raw holds, byte for byte" \
    'python3 -c "import sys; a = open(sys.argv[1], \"rb\").read(); b = open(sys.argv[2], \"rb\").read(); sys.exit(a[a.index(b\"\\n\\n\") + 2:] != b)" "$T/body" "$V/ct_head_crop64_int16.raw"'
printf '\001\000' >"$T/one"
code=$(status POST "/models/$ID/edit?region=32,32,32,1,1,1" -H "$A" -H 'Content-Type: application/octet-stream' --data-binary @"$T/one")
status GET "/models/$ID/volume" -H "$A" >/dev/null
nrrd "$T/body" >"$T/nrrd.json"
check "after an edit of one sample the volume holds the edit" '[ "$code" = 200 ] && [ "$(val at)" = 1 ]'
code=$(status GET "/models/$ID/volume" -H "$B")
check "another token's model: 404 problem+json" '[ "$code" = 404 ] && is_problem 404'
code=$(status GET "/models/$ID/volume")
check "without a token: 401" '[ "$code" = 401 ]'
code=$(status GET "/models/0123456789abcdef0123456789abcdef/volume" -H "$A")
check "no such model: 404 problem+json" '[ "$code" = 404 ] && is_problem 404'
code=$(status POST "/model" -H "$A" -H 'Content-Type: application/json' --data-binary @"$C"); CID=$(field id)
code=$(status GET "/models/$CID/volume" -H "$A")
check "a contour model (no samples): 409 problem+json saying so" '[ "$code" = 409 ] && is_problem 409 && grep -q "no volume of samples" "$T/body"'
code=$(status POST "/isosurface?iso=100" -H "$A" -F header=@"$V/ct_head_256x256x108_int16.mhd" -F data=@"$V/ct_head_256x256x108_int16.raw")
check "(a volume over max-volume is not even taken)" '[ "$code" = 413 ] || [ "$code" = 422 ]'

# ---- a series' samples ----
storescu -aet STORESCU -aec SURFD 127.0.0.1 "$DP" "$DD"/*.dcm >"$T/scu" 2>&1
status GET /series -H "$A" >/dev/null
SUID=$(field series 0 uid)
status GET "/series/$SUID" -H "$A" >/dev/null; cp "$T/body" "$T/series.json"
code=$(status GET "/series/$SUID/volume" -H "$B")
nrrd "$T/body" >"$T/nrrd.json"
check "GET /series/{uid}/volume: 200 NRRD, int16 (HU), the series' dims" \
    '[ "$code" = 200 ] && [ "$(val type)" = int16 ] && [ "$(val dims)" = "$(python3 -c "import json,sys; print(json.load(open(sys.argv[1]))[\"dims\"])" "$T/series.json")" ] && [ "$(val rest)" = 0 ]'
check "... its spacing the series' (PixelSpacing, slice distance), air below -900 HU and bone above 200" 'python3 -c "
import json, sys
n, s = json.load(open(sys.argv[1])), json.load(open(sys.argv[2]))
sp = [abs(sum(x * x for x in d)) ** 0.5 for d in n[\"dirs\"]]
sys.exit(0 if all(abs(a - b) < 1e-6 for a, b in zip(sorted(sp), sorted(s[\"spacing\"]))) and n[\"lo\"] < -900 and n[\"hi\"] > 200 else 1)" "$T/nrrd.json" "$T/series.json"'
code=$(status POST "/isosurface?iso=226.5&series=$SUID" -H "$A"); cp "$T/body" "$T/iso.json"
check "... its box holds the series' isosurface, to a cell (closed: one cell out; origin and directions in patient LPS)" '[ "$code" = 201 ] && python3 -c "
import json, sys
n, m = json.load(open(sys.argv[1])), json.load(open(sys.argv[2]))
c = [[n[\"origin\"][q] + sum(((k >> a) & 1) * (n[\"dims\"][a] - 1) * n[\"dirs\"][a][q] for a in range(3)) for q in range(3)] for k in range(8)]
lo = [min(p[q] for p in c) for q in range(3)]; hi = [max(p[q] for p in c) for q in range(3)]
b = m[\"bounds\"]
s = [sum(x * x for x in d) ** 0.5 for d in n[\"dirs\"]]
sys.exit(0 if all(lo[q] - s[q] <= b[0][q] < b[1][q] <= hi[q] + s[q] for q in range(3)) else 1)" "$T/nrrd.json" "$T/iso.json"'
code=$(status GET "/series/1.2.3.4.5/volume" -H "$A")
check "no such series: 404 problem+json" '[ "$code" = 404 ] && is_problem 404'
code=$(status GET "/series/not-a-uid/volume" -H "$A")
check "a path that is no UID: 404" '[ "$code" = 404 ]'

# ---- the PACS configured ----
code=$(status GET /pacs -H "$A")
check "GET /pacs: the PACS by name and protocol" '[ "$code" = 200 ] && [ "$(field pacs 0 name)" = orthanc ] && [ "$(field pacs 0 protocol)" = dicomweb ] && [ "$(field pacs 1 name)" = scanner ] && [ "$(field pacs 1 protocol)" = dimse ]'
check "... without their addresses" '! grep -q "127.0.0.1\|SCANNER" "$T/body"'
finish
