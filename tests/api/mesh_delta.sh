#!/bin/sh
# Model versions and the mesh delta layout (API.md, "Interactive isosurfaces"; issue 45's first
# part, what the page's 3D view loads): every model resource has `version` (1 when made, +1 an
# edit); GET /models/{id}/mesh?format=delta&since=0 is the whole mesh in the binary layout
# ("SFMD", from, to, removed, added, each added triangle's id and corners), its triangles exactly
# the STL's; since=the version is an empty delta; after an edit, since=0 is the edited mesh by its
# stable ids and since=1 the edit's change; a version older than the journal kept is 410 at ?since
# (tests/api/mesh_journal.sh); after the version, or not a number, 422.
. "$(dirname "$0")/lib.inc"
V="${SURFD_DATA:-../shared/data}/volumes"
CT="$V/ct_head_crop64_int16.raw"
C="${SURFD_DATA:-../shared/data}/contours/dicompyler_heart.json"
[ -f "$CT" ] && [ -f "$C" ] || { bad "../shared/data not found"; checks_done; exit 1; }
RAW='Content-Type: application/octet-stream'
start_daemon "$T/d" || exit 1
field() { python3 -c "import json,sys; print(json.load(open(sys.argv[1])).get(sys.argv[2]))" "$T/body" "$1"; }
pointer_is() { grep -q "\"pointer\":\"$1\"" "$T/body"; }
# delta_is FILE FROM TO ADDED [STL [ids]]: the delta's header, and its added triangles those of STL
# in order, ids 0 .. n-1 (with "ids": the same triangles by distinct ids, in any order)
delta_is() {
    python3 - "$@" <<'PY'
import struct, sys
d = open(sys.argv[1], "rb").read()
want = [int(x) for x in sys.argv[2:5]]
magic, frm, to, nrem, nadd = d[:4], *struct.unpack_from("<4I", d, 4)
assert magic == b"SFMD" and [frm, to, nadd] == want and nrem == 0, (magic, frm, to, nrem, nadd, want)
assert len(d) == 20 + 40 * nadd, len(d)
if len(sys.argv) > 5:
    s = open(sys.argv[5], "rb").read()
    n = struct.unpack_from("<I", s, 80)[0]
    assert n == nadd, (n, nadd)
    got = [struct.unpack_from("<I9f", d, 20 + 40 * k) for k in range(n)]
    stl = [struct.unpack_from("<12f", s, 84 + 50 * k)[3:] for k in range(n)]
    if len(sys.argv) > 6:
        assert len({g[0] for g in got}) == n and sorted(g[1:] for g in got) == sorted(stl)
    else:
        assert all(g[0] == k and tuple(g[1:]) == stl[k] for k, g in enumerate(got))
PY
}

code=$(status POST "/isosurface?iso=300&dims=64,64,64&type=int16&spacing=0.9570312,0.9570312,1.5" -H "$RAW" --data-binary @"$CT")
ID=$(field id); TRI=$(field triangles)
check "a new isosurface model: version 1" '[ "$code" = 201 ] && [ "$(field version)" = 1 ]'
status GET "/models/$ID/mesh?format=stl" >/dev/null; cp "$T/body" "$T/v1.stl"
code=$(status GET "/models/$ID/mesh?format=delta&since=0"); cp "$T/body" "$T/d0"
check "mesh?format=delta&since=0: application/vnd.surfd.mesh-delta, from 0 to 1, every triangle added (ids 0..n-1), the STL's triangles in order" \
    '[ "$code" = 200 ] && header Content-Type | grep -q "application/vnd.surfd.mesh-delta" && delta_is "$T/d0" 0 1 "$TRI" "$T/v1.stl"'
code=$(status GET "/models/$ID/mesh?format=delta"); cp "$T/body" "$T/dnone"
check "... since left out: 0" '[ "$code" = 200 ] && cmp -s "$T/dnone" "$T/d0"'
code=$(status GET "/models/$ID/mesh?format=delta&since=1"); cp "$T/body" "$T/d1"
check "since=1 (the version): an empty delta from 1 to 1" '[ "$code" = 200 ] && delta_is "$T/d1" 1 1 0'
python3 tests/tools/edit_tool.py block 12 1400 -100 4.5 "$T/ball.raw"
code=$(status POST "/models/$ID/edit?region=20,24,17,12,12,12" -H "$RAW" --data-binary @"$T/ball.raw")
status GET "/models/$ID" >/dev/null
check "an edit: version 2" '[ "$code" = 200 ] && [ "$(field version)" = 2 ]'
TRI2=$(field triangles)
status GET "/models/$ID/mesh?format=stl" >/dev/null; cp "$T/body" "$T/v2.stl"
code=$(status GET "/models/$ID/mesh?format=delta&since=0"); cp "$T/body" "$T/d0"
check "... since=0: from 0 to 2, the edited STL's triangles by their stable ids" '[ "$code" = 200 ] && delta_is "$T/d0" 0 2 "$TRI2" "$T/v2.stl" ids'
code=$(status GET "/models/$ID/mesh?format=delta&since=1")
check "... since=1: the edit's change, from 1 to 2 (triangles taken out and put in)" '[ "$code" = 200 ] && python3 -c "
import struct, sys; d = open(sys.argv[1], \"rb\").read(); f, t, r, a = struct.unpack_from(\"<4I\", d, 4)
sys.exit(not (d[:4] == b\"SFMD\" and (f, t) == (1, 2) and r > 0 and a > 0 and len(d) == 20 + 4 * r + 40 * a))" "$T/body"'
code=$(status GET "/models/$ID/mesh?format=delta&since=3")
check "since after the version: 422 at ?since" '[ "$code" = 422 ] && pointer_is "?since"'
code=$(status GET "/models/$ID/mesh?format=delta&since=x")
check "since not a number: 422 at ?since" '[ "$code" = 422 ] && pointer_is "?since"'
code=$(status POST /model -H 'Content-Type: application/json' --data-binary @"$C")
MID=$(field id); MTRI=""
check "a contour model: version 1" '[ "$code" = 201 ] && [ "$(field version)" = 1 ]'
status GET "/models/$MID/mesh?format=stl" >/dev/null; cp "$T/body" "$T/m.stl"
MTRI=$(python3 -c "import struct,sys; print(struct.unpack_from('<I', open(sys.argv[1],'rb').read(), 80)[0])" "$T/m.stl")
code=$(status GET "/models/$MID/mesh?format=delta&since=0"); cp "$T/body" "$T/md"
check "... its delta since=0: its default mesh's triangles, as its STL" '[ "$code" = 200 ] && delta_is "$T/md" 0 1 "$MTRI" "$T/m.stl"'
code=$(status GET "/models/0123456789abcdef0123456789abcdef/mesh?format=delta&since=0")
check "an unknown model: 404" '[ "$code" = 404 ]'
checks_done
