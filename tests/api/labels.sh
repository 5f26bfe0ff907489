#!/bin/sh
# Label maps over POST /isosurface (issue 47: 5): the shared CT crop cut into labels 1, 2 and 5 (0
# the background) as NRRD with 3D Slicer's segment names, MetaImage and NIfTI (int16 with a label
# table extension, int32 with intent_name alone). ?label=N is the isosurface of N's mask at 0.5,
# triangle for triangle, against the same route given the mask as its own volume. ?labels=all makes
# one model a label in one job ({"models": [...]}), named from the file: each closed and oriented,
# the labels that touch sharing their boundary (every triangle of A facing B is one of B's, turned
# round, as many as each model's neighbours say), their volumes adding up to the labelled voxels'.
# Bad requests: a label not in the map, a float volume, label and labels together, iso with them,
# more labels than max-labels (from the header's segments, and from the samples).
. "$(dirname "$0")/lib.inc"
CT="${SURFD_DATA:-../shared/data}/volumes/ct_head_crop64_int16.raw"
[ -f "$CT" ] || { bad "../shared/data/volumes not found"; checks_done; exit 1; }
start_daemon "$T/d" --threads 2 || exit 1

python3 - "$CT" "$T" <<'PY'
import array, struct, sys
sys.path.insert(0, "tests/tools")
import label_write as lw, nifti_write as nw
ct, t = sys.argv[1], sys.argv[2]
hu = array.array("h", open(ct, "rb").read())
d, sp, org = (64, 64, 64), (0.9570312, 0.9570312, 1.5), (-100, -120, -50)
lab = lw.labels(hu, [(-500, 60, 1), (60, 700, 2), (700, 1e9, 5)])   # soft tissue, dense, bone; 0 air
open(t + "/voxels", "w").write("%d" % sum(1 for v in lab if v))
i16, mask2 = lw.pack(lab, "int16"), lw.pack([1 if v == 2 else 0 for v in lab], "uint8")
lw.nrrd(t + "/seg.nrrd", i16, d, "int16", segments=[(1, "soft tissue"), (2, "dense"), (5, "bone")], gz=True,
        spacing=sp, origin=org)
lw.nrrd(t + "/mask2.nrrd", mask2, d, "uint8", spacing=sp, origin=org)
lw.mha(t + "/seg.mha", lw.pack(lab, "uint8"), d, "uint8", spacing=sp, origin=org)
lw.nrrd(t + "/float.nrrd", lw.pack([float(v) for v in lab], "float32"), d, "float32", spacing=sp, origin=org)
ras = [[-sp[0], 0, 0, 100], [0, -sp[1], 0, 120], [0, 0, sp[2], -50]]   # LPS +x, +y, +z from (-100, -120, -50)
table = (b'<LabelTable><Label Key="1" Red="1" Green="0" Blue="0" Alpha="1"><![CDATA[soft tissue]]></Label>'
         b'<Label Key="2">dense &amp; calcified</Label><Label Key="5">bone</Label></LabelTable>')
nw.write(t + "/seg.nii.gz", i16, d, 4, 16, sform=ras, gz=True, extensions=[(32, table)])
nw.write(t + "/i32.nii", struct.pack("<%di" % len(lab), *lab), d, 8, 32, sform=ras, intent_name=b"tissue")
lw.mha(t + "/u16.mha", lw.pack([v * 13107 for v in lab], "uint16"), d, "uint16", spacing=sp, origin=org)  # 13107, 26214, 65535
# a map of 5 labels named by its header (max-labels refused from the header) and 3 by its samples (from the samples)
lw.nrrd(t + "/named5.nrrd", i16, d, "int16", segments=[(k, "s%d" % k) for k in (1, 2, 3, 4, 5)], spacing=sp, origin=org)
PY

field() { python3 -c "import json,sys; print(json.load(open(sys.argv[1])).get(sys.argv[2]))" "$T/body" "$1"; }
pointer_is() { grep -q "\"pointer\":\"$1\"" "$T/body"; }

# ?label=N: the mask's isosurface, triangle for triangle
code=$(status POST "/isosurface?iso=0.5" -H 'Content-Type: application/x-nrrd' --data-binary @"$T/mask2.nrrd")
check "the mask of label 2 as its own volume at iso 0.5: 201" '[ "$code" = 201 ]'
MASK=$(field id)
code=$(status POST "/isosurface?label=2" -H 'Content-Type: application/x-nrrd' --data-binary @"$T/seg.nrrd")
check "?label=2 of the NRRD: 201, named from its segment (\"dense\"), label 2, iso 0.5" \
    '[ "$code" = 201 ] && [ "$(field name)" = dense ] && [ "$(field label)" = 2 ] && [ "$(field iso)" = 0.5 ]'
ONE=$(field id)
curl -s -o "$T/mask.stl" "$URL/models/$MASK/mesh?format=stl"
curl -s -o "$T/one.stl" "$URL/models/$ONE/mesh?format=stl"
tail -c +81 "$T/mask.stl" >"$T/mask.tri"
tail -c +81 "$T/one.stl" >"$T/one.tri"
check "?label=2's mesh is the mask's isosurface at 0.5, triangle for triangle (the STLs past their headers)" \
    '[ -s "$T/one.tri" ] && cmp -s "$T/mask.tri" "$T/one.tri" && python3 tests/tools/stl_check.py "$T/one.stl" - >/dev/null'
code=$(status POST "/models/$ONE/edit?region=0,0,0,1,1,1" -H 'Content-Type: application/octet-stream' --data-binary 'x')
check "a label's model is not edited: 409 saying why" '[ "$code" = 409 ] && grep -q "label map" "$T/body"'

# ?labels=all: one model a label, shared boundaries
shared() { # shared PREFIX: each model of $T/body closed, sharing its boundary, volumes adding up
    python3 - "$T/body" "$URL" "$T/voxels" "$1" <<'PY'
import json, struct, sys, urllib.request
ans, url, voxels, want = json.load(open(sys.argv[1])), sys.argv[2], int(open(sys.argv[3]).read()), sys.argv[4].split(",")
models = ans["models"]
names = [m["name"] for m in models]
assert names == want, (names, want)
tris, total = {}, 0.0
def canon(t):
    k = t.index(min(t))
    return t[k:] + t[:k]
for m in models:
    data = urllib.request.urlopen(url + m["links"]["mesh"]).read()
    n = struct.unpack_from("<I", data, 80)[0]
    ts, edges = [], {}
    for k in range(n):
        v = struct.unpack_from("<12f", data, 84 + 50 * k)[3:]
        t = (v[0:3], v[3:6], v[6:9])
        ts.append(canon(t))
        for i in range(3):
            e = (t[i], t[(i + 1) % 3])
            edges[e] = edges.get(e, 0) + 1
    bad = sum(1 for (a, b), c in edges.items() if c != 1 or edges.get((b, a)) != 1)
    assert bad == 0 and m["boundary_edges"] == 0 and m["nonmanifold_edges"] == 0, (m["name"], bad)
    tris[m["label"]] = set(ts)
    total += m["volume_mm3"]
for m in models:
    for nb in m["neighbours"]:
        if nb["label"] == 0:
            continue
        other = tris[nb["label"]]
        common = sum(1 for t in tris[m["label"]] if canon((t[0], t[2], t[1])) in other)
        back = [x["triangles"] for x in next(o for o in models if o["label"] == nb["label"])["neighbours"]
                if x["label"] == m["label"]]
        assert common == nb["triangles"] == back[0], (m["label"], nb, common, back)
vox = voxels * 0.9570312 * 0.9570312 * 1.5
print("volumes %.1f mm3, labelled voxels %.1f mm3 (%+.3f %%)" % (total, vox, 100 * (total - vox) / vox))
assert abs(total - vox) < 0.01 * vox
PY
}
code=$(status POST "/isosurface?labels=all" -H 'Content-Type: application/x-nrrd' --data-binary @"$T/seg.nrrd")
check "?labels=all of the NRRD: 201, three models named from its segments, Location the first's" \
    '[ "$code" = 201 ] && grep -q "\"models\":\[" "$T/body" && header Location | grep -q "^/models/$(header X-Job-Id)$"'
check "each closed and oriented, every triangle of A facing B one of B turned round (as many as both say), volumes adding up to the labelled voxels within 1 %" \
    'shared "soft tissue,dense,bone"'
JOB=$(header X-Job-Id)
check "GET /models lists the three" 'curl -s "$URL/models" | python3 -c "
import json, sys; ms = json.load(sys.stdin)[\"models\"]; sys.exit(0 if sum(m.get(\"method\") == \"multi-label\" for m in ms) == 3 else 1)"'
check "GET /jobs/{id}/result: the same {models}" 'curl -s "$URL/jobs/$JOB/result" | grep -q "\"name\":\"bone\""'
code=$(status POST "/isosurface?labels=all&name=CT" --data-binary @"$T/seg.mha")
check "MetaImage (no names: \"label N\"), ?name before each" '[ "$code" = 201 ] && shared "CT label 1,CT label 2,CT label 5"'
code=$(status POST "/isosurface?labels=all" -H 'Content-Type: application/gzip' --data-binary @"$T/seg.nii.gz")
check "NIfTI, gzip, int16: named by its label table extension (CDATA, entities)" \
    '[ "$code" = 201 ] && shared "soft tissue,dense & calcified,bone"'
code=$(status POST "/isosurface?labels=all" --data-binary @"$T/i32.nii")
check "NIfTI int32, intent_name only: \"tissue N\"" '[ "$code" = 201 ] && shared "tissue 1,tissue 2,tissue 5"'

code=$(status POST "/isosurface?labels=all" --data-binary @"$T/u16.mha")
check "uint16 labels 13107, 26214 and 65535: the same surfaces" '[ "$code" = 201 ] && shared "label 13107,label 26214,label 65535"'

refused() { # refused QUERY FILE STATUS POINTER TEXT
    want=$3 at=$4 text=$5
    code=$(status POST "/isosurface?$1" --data-binary @"$T/$2")
    check "?$1 ($2): $3 at $4, \"$5\"" '[ "$code" = "$want" ] && is_problem "$want" && pointer_is "$at" && grep -q "$text" "$T/body"'
}
refused "label=3" seg.nrrd 422 "?label" "label 3 is not in the map; its labels are 1, 2 and 5"
refused "label=300" seg.mha 422 "?label" "uint8 samples hold 0 to 255"
refused "label=0" seg.nrrd 422 "?label" "background"
refused "label=two" seg.nrrd 422 "?label" "whole number"
refused "label=2" float.nrrd 422 "?label" "whole numbers"
refused "labels=all" float.nrrd 422 "?labels" "whole numbers"
refused "label=2&labels=all" seg.nrrd 422 "?labels" "together"
refused "labels=some" seg.nrrd 422 "?labels" "labels is all"
refused "labels=all&iso=1" seg.nrrd 422 "?iso" "implied"
refused "labels=all&levels=2" seg.nrrd 422 "?levels" "full resolution"
code=$(status POST "/matrix-model?labels=all" --data-binary @"$T/seg.nrrd")
check "/matrix-model?labels=all: 422 at ?labels" '[ "$code" = 422 ] && pointer_is "?labels"'

# max-labels: refused from the header's segments before the job runs, else from the samples
stop_daemon
start_daemon "$T/d" --threads 2 --max-labels 2 || exit 1
code=$(status POST "/isosurface?labels=all" --data-binary @"$T/named5.nrrd" -H 'Prefer: respond-async')
check "max-labels 2, a header naming 5 segments: 422 at ?labels at once, no job" \
    '[ "$code" = 422 ] && pointer_is "?labels" && grep -q "names 5 labels" "$T/body" && [ -z "$(header X-Job-Id)" ]'
code=$(status POST "/isosurface?labels=all" --data-binary @"$T/seg.mha")
check "max-labels 2, a MetaImage of 3 labels: the job's 422 at ?labels, before any surface" \
    '[ "$code" = 422 ] && pointer_is "?labels" && grep -q "has 3 labels" "$T/body"'
code=$(status POST "/isosurface?label=5" --data-binary @"$T/seg.mha")
check "max-labels does not bound ?label=N: 201" '[ "$code" = 201 ]'
stop_daemon
start_daemon "$T/d" --threads 2 || exit 1

# the clients
SURFD_URL=$URL ./build/surfctl isosurface "$T/seg.nrrd" --labels all -o "$T/c.stl" >"$T/body" 2>/dev/null; rc=$?
check "surfctl isosurface FILE --labels all -o OUT.stl: the models, each label's mesh in OUT-N.stl" \
    '[ $rc -eq 0 ] && shared "soft tissue,dense,bone" && for k in 1 2 5; do python3 tests/tools/stl_check.py "$T/c-$k.stl" - >/dev/null || exit 1; done'
SURFD_URL=$URL ./build/surfctl isosurface "$T/seg.nrrd" --label 2 -o "$T/c2.stl" >"$T/body" 2>/dev/null; rc=$?
check "surfctl isosurface FILE --label 2: the mask's mesh" '[ $rc -eq 0 ] && tail -c +81 "$T/c2.stl" | cmp -s - "$T/one.tri"'
check "the Python client's isosurface(FILE, labels=\"all\") and (label=2)" 'SURFD_URL=$URL PYTHONPATH=client/python python3 -c "
import json, surfd, sys
c = surfd.Client(token=\"\")
json.dump(c.isosurface(sys.argv[1], labels=\"all\"), open(sys.argv[2], \"w\"))
sys.exit(0 if c.isosurface(sys.argv[1], label=2)[\"name\"] == \"dense\" else 1)" "$T/seg.nrrd" "$T/body" && shared "soft tissue,dense,bone"'
check "the offline CLI: surfd isosurface FILE --labels all gives the same models" \
    '$S isosurface "$T/seg.nrrd" --labels all >"$T/off.json" && python3 -c "
import json, sys
a, b = json.load(open(sys.argv[1]))[\"models\"], json.load(open(sys.argv[2]))[\"models\"]
sys.exit(0 if [(m[\"name\"], m[\"triangles\"], m[\"neighbours\"]) for m in a] == [(m[\"name\"], m[\"triangles\"], m[\"neighbours\"]) for m in b] else 1)" "$T/off.json" "$T/body"'
check "the daemon up after all of them" 'alive'
finish
