#!/bin/sh
# The clients follow a model's changes by mesh deltas (issue 45): surfctl edit --since V and
# surfctl iso MODEL VALUE --since V write the delta a client holding version V applies; surfctl
# mesh --format delta --since V the same; the Python client's MeshCopy loads since=0, applies each
# change and, when the journal no longer reaches back to its version (410), loads the whole mesh
# again; both end holding exactly the STL's triangles.
. "$(dirname "$0")/lib.inc"
C=./build/surfctl
V="${SURFD_DATA:-../shared/data}/volumes"
CT="$V/ct_head_crop64_int16.raw"
[ -f "$CT" ] || { bad "../shared/data not found"; checks_done; exit 1; }
start_daemon "$T/d" --journal-kept 2 || exit 1
export SURFD_URL="$URL"
python3 tests/tools/edit_tool.py block 10 1500 -200 3.5 "$T/ball.raw"
$C isosurface "$CT" --dims 64,64,64 --type int16 --spacing 0.9570312,0.9570312,1.5 --iso 226.5 --levels 2 --max-error 0.5 -o "$T/first.stl" >"$T/m.json" 2>"$T/m.err"
ID=$(python3 -c "import json,sys; print(json.load(open(sys.argv[1]))['id'])" "$T/m.json")
# apply DELTA...: the deltas applied in order to $T/copy (a since=0 delta first), the copy against the STL
applied() {
    python3 - "$@" <<'PY'
import struct, sys
t, version = {}, 0
for f in sys.argv[1:-1]:
    d = open(f, "rb").read()
    frm, to, nr, na = struct.unpack_from("<4I", d, 4)
    assert d[:4] == b"SFMD" and frm == version, (f, frm, version)
    for r in struct.unpack_from("<%dI" % nr, d, 20):
        del t[r]
    for k in range(na):
        tid, *c = struct.unpack_from("<I9f", d, 20 + 4 * nr + 40 * k)
        t[tid] = tuple(c)
    version = to
s = open(sys.argv[-1], "rb").read(); n = struct.unpack_from("<I", s, 80)[0]
sys.exit(0 if sorted(t.values()) == sorted(struct.unpack_from("<12f", s, 84 + 50 * k)[3:] for k in range(n)) else 1)
PY
}
$C mesh "$ID" -o "$T/d0" --format delta --since 0; rc0=$?
$C edit "$ID" "$T/ball.raw" --region 20,24,17,10,10,10 -o "$T/d1" --since 1 >"$T/e.json"; rc1=$?
$C iso "$ID" 400 -o "$T/d2" --since 2 >"$T/i.json"; rc2=$?
$C mesh "$ID" -o "$T/now.stl"
check "surfctl mesh --format delta --since 0, edit --since 1, iso 400 --since 2: applied in order, the STL's triangles" \
    '[ $rc0 = 0 ] && [ $rc1 = 0 ] && [ $rc2 = 0 ] && grep -q "\"version\":3" "$T/i.json" && applied "$T/d0" "$T/d1" "$T/d2" "$T/now.stl"'
$C iso "$ID" -500 -o "$T/neg.stl" >/dev/null; rc=$?
check "surfctl iso with a negative value: 200, the mesh to OUT.stl" '[ $rc = 0 ] && python3 tests/tools/stl_check.py "$T/neg.stl" - >/dev/null'
$C iso "$ID" 99999 >/dev/null 2>"$T/err"; rc=$?
check "surfctl iso outside the samples' range: its job failed (exit 1), the problem on stderr naming the range and ?value" '[ $rc = 1 ] && grep -q "samples run from .* at ?value" "$T/err"'
PYTHONPATH=client/python python3 - "$URL" "$ID" "$T/ball.raw" "$T/py.stl" >"$T/py.out" 2>&1 <<'PY'
import struct, sys, surfd
c = surfd.Client(sys.argv[1], token="")
mid, ball = sys.argv[2], open(sys.argv[3], "rb").read()
copy = surfd.MeshCopy(c, mid)
v0 = copy.version
c.edit(mid, ball, region=(30, 8, 40, 10, 10, 10))
copy.update()
assert copy.version == v0 + 1, (copy.version, v0)
c.iso(mid, 226.5)
copy.update()
s = c.mesh(mid)
n = struct.unpack_from("<I", s, 80)[0]
stl = sorted(struct.unpack_from("<12f", s, 84 + 50 * k)[3:] for k in range(n))
assert sorted(copy.triangles.values()) == stl, "copy != STL"
# fall behind the journal (journal-kept 2): the update loads the whole mesh again
behind = surfd.MeshCopy(c, mid)
for r in ((8, 40, 3), (12, 30, 30), (40, 20, 30), (21, 25, 18)):
    c.edit(mid, ball, region=r + (10, 10, 10))
behind.update()
s = c.mesh(mid)
n = struct.unpack_from("<I", s, 80)[0]
assert sorted(behind.triangles.values()) == sorted(struct.unpack_from("<12f", s, 84 + 50 * k)[3:] for k in range(n))
try:
    c.mesh(mid, format="delta", since=1)
    raise SystemExit("since=1 was answered")
except surfd.SurfdError as e:
    assert e.status == 410 and e.pointer == "?since", e
print("ok", copy.version, behind.version)
PY
check "Python MeshCopy: loaded, an edit and an iso change applied by id, the STL's triangles; behind the journal, loaded again (410 seen)" 'grep -q "^ok" "$T/py.out"'
checks_done
