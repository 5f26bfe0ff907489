#!/bin/sh
# One table of input formats (issue 47: 1, api/formats.h): GET /formats lists it; every route takes
# every media type the table gives it (never 415) and refuses any other with a 415 that lists the
# table's; ?format= takes every name and alias of a route's formats (never 400 at ?format) and
# refuses others listing them; openapi.yaml's request bodies name exactly the table's media (and the
# ones sniffed); the Python client picks a file's type from the table as surfctl does, and surfctl
# sends what the table says (its requests seen through the daemon's answers).
. "$(dirname "$0")/lib.inc"
start_daemon "$T/d" || exit 1
code=$(status GET /formats); cp "$T/body" "$T/formats.json"
check "GET /formats: the table, each format with names, extensions, media and routes" '[ "$code" = 200 ] && python3 -c "
import json, sys
f = json.load(open(sys.argv[1]))[\"formats\"]
sys.exit(0 if len(f) >= 10 and all(x[\"name\"] and x[\"media\"] and x[\"routes\"] and x[\"extensions\"] for x in f) else 1)" "$T/formats.json"'
# the table's (route media) and (route name) pairs, and the routes that take ?format=
python3 -c "
import json, sys
d = json.load(open(sys.argv[1]))
for f in d['formats']:
    for r in f['routes']:
        for m in f['media']:
            print('media', r, m)
        for n in [f['name']] + f['aliases']:
            print('name', r, n)
for m, routes in d['sniffed_media'].items():
    for r in routes:
        print('media', r, m)" "$T/formats.json" >"$T/pairs"
bad415=0 badfmt=0 n=0
while read -r what route value; do
    n=$((n + 1))
    if [ "$what" = media ]; then
        c=$(status POST "$route" -H "Content-Type: $value" --data-binary 'x')
        [ "$c" = 415 ] && { bad415=$((bad415 + 1)); echo "  $route 415 for $value"; }
    elif [ "$route" != /model ]; then
        c=$(status POST "$route?format=$value" --data-binary 'x')
        [ "$c" = 400 ] && grep -q '"pointer":"?format"' "$T/body" && { badfmt=$((badfmt + 1)); echo "  $route refused ?format=$value"; }
    fi
done <"$T/pairs"
check "every route takes every media type the table gives it ($n pairs): no 415" '[ "$bad415" = 0 ] && [ "$n" -gt 40 ]'
check "... and every name and alias of its formats as ?format=" '[ "$badfmt" = 0 ]'
for route in /render /volume /model /isosurface /matrix-model; do
    code=$(status POST "$route" -H 'Content-Type: image/png' --data-binary x)
    check "$route: image/png is a 415 listing every type the table gives the route" '[ "$code" = 415 ] && python3 -c "
import json, sys
d = json.load(open(sys.argv[1])); detail = json.load(open(sys.argv[2]))[\"detail\"]
want = [m for f in d[\"formats\"] if sys.argv[3] in f[\"routes\"] for m in f[\"media\"][:1]]
sys.exit(0 if want and all(m in detail for m in want) else 1)" "$T/formats.json" "$T/body" "$route"'
done
code=$(status POST "/volume?format=step" --data-binary x)
check "?format=step on /volume: 400 at ?format naming the route's formats" '[ "$code" = 400 ] && grep -q "\"pointer\":\"?format\"" "$T/body" && grep -q "json, iges, bpt, nurbs or dicom" "$T/body"'
code=$(status POST "/volume?format=wrl" --data-binary @"${SURFD_DATA:-../shared/data}/scenes/duck1.nurbs")
check "?format=wrl (an alias) on /volume as on /render: the duck's volume" '[ "$code" = 200 ] && grep -q "\"volume_mm3\"" "$T/body"'
check "openapi.yaml: each route's request body names exactly the table's media types and the sniffed ones" 'python3 -c "
import json, sys, yaml
d = json.load(open(sys.argv[1])); spec = yaml.safe_load(open(\"api/openapi.yaml\"))
ok = True
for route in [\"/render\", \"/volume\", \"/model\", \"/isosurface\", \"/matrix-model\"]:
    want = {m for f in d[\"formats\"] if route in f[\"routes\"] for m in f[\"media\"]}
    want |= {m for m, rs in d[\"sniffed_media\"].items() if route in rs and m != \"application/x-www-form-urlencoded\"}
    body = spec[\"paths\"][route][\"post\"][\"requestBody\"]
    if \"\$ref\" in body:
        body = spec[\"components\"][\"requestBodies\"][body[\"\$ref\"].split(\"/\")[-1]]
    have = set(body[\"content\"])
    if want != have:
        ok = False
        print(\"  \", route, \"missing\", sorted(want - have), \"extra\", sorted(have - want))
sys.exit(0 if ok else 1)" "$T/formats.json"'
check "the Python client's type for each extension on each route is the table's" '/usr/bin/python3 -c "
import json, sys
from pathlib import Path
sys.path.insert(0, \"client/python\"); import surfd
d = json.load(open(sys.argv[2])); c = surfd.Client(sys.argv[1])
bad = [(r, e) for f in d[\"formats\"] for r in f[\"routes\"] for e in f[\"extensions\"]
       if c._media_of(Path(\"a\" + e), r) != next(g[\"media\"][0] for g in d[\"formats\"] if r in g[\"routes\"] and
                                                   any((\"a\" + e).endswith(x) for x in g[\"extensions\"]))]
sys.exit(1 if bad else 0)" "$URL" "$T/formats.json"'
printf '\211PNG\r\n\032\n0000000000000000' >"$T/x.png"
for route in "/isosurface?iso=1" /render /volume /model; do
    code=$(status POST "$route" --data-binary @"$T/x.png")
    check "a PNG posted to $route without a type: 400 saying it is a PNG image, not read, and what the route reads" '[ "$code" = 400 ] && grep -q "the body is a PNG image, which is not read" "$T/body" && grep -q "GET /formats" "$T/body"'
done
cp "${SURFD_DATA:-../shared/data}/volumes/ct_head_crop64_int16.raw" "$T/crop.nii.gz"
SURFD_URL="$URL" ./build/surfctl isosurface "$T/crop.nii.gz" --iso 1 -o "$T/x.stl" >/dev/null 2>"$T/err"
check "surfctl sends a .nii.gz as the table's application/x-nifti (read as NIfTI: refused as not one, not as raw samples)" 'grep -q "NIfTI" "$T/err"'
finish
