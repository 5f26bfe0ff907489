#!/bin/sh
# NIfTI-1 and NIfTI-2 over POST /isosurface (issue 47: 5): the shared CT crop written as NIfTI
# (tests/tools/nifti_write.py, by the standard's offsets) by sform, qform and the pixdims alone,
# gzip or not, either byte order, scaled and as float64, each giving the mesh the raw samples give
# at the place the affine says in patient coordinates (RAS+ to DICOM's LPS); a left-handed affine
# still a closed mesh facing out; every kind of bad header refused with what it is.
. "$(dirname "$0")/lib.inc"
CT="${SURFD_DATA:-../shared/data}/volumes/ct_head_crop64_int16.raw"
[ -f "$CT" ] || { bad "../shared/data/volumes not found"; checks_done; exit 1; }
start_daemon "$T/d" --threads 2 || exit 1
SX=0.9570312 SZ=1.5

python3 - "$CT" "$T" "$SX" "$SZ" <<'PY'
import array, struct, sys
sys.path.insert(0, "tests/tools")
import nifti_write as nw
ct, t, sx, sz = sys.argv[1], sys.argv[2], float(sys.argv[3]), float(sys.argv[4])
le = open(ct, "rb").read()
big = array.array("h", le); big.byteswap(); big = big.tobytes()
f64 = struct.pack("<%dd" % (len(le) // 2), *struct.unpack("<%dh" % (len(le) // 2), le))
d = (64, 64, 64)
ras = [[-sx, 0, 0, 100], [0, -sx, 0, 120], [0, 0, sz, -50]]         # LPS: +x, +y, +z from (-100, -120, -50)
nw.write(t + "/a.nii", le, d, 4, 16, sform=ras)
nw.write(t + "/a2.nii.gz", big, d, 4, 16, sform=ras, version=2, gz=True, big=True)
nw.write(t + "/q.nii", le, d, 4, 16, qform=(0, 0, 0, 100, 120, -50, 1), pixdim=(sx, sx, sz))   # RAS as stored
h = 0.5 ** 0.5                                                      # 90 degrees about z, qfac -1: k reversed
nw.write(t + "/q90.nii", le, d, 4, 16, qform=(0, 0, h, 100, 120, -50, -1), pixdim=(sx, sx, sz))
nw.write(t + "/l.nii", le, d, 4, 16, sform=[[-sx, 0, 0, 100], [0, sx, 0, 120], [0, 0, sz, -50]])  # left-handed
nw.write(t + "/nan.nii", le, d, 4, 16, sform=ras, slope=float("nan"), inter=float("nan"))  # nibabel's "no scaling"
nw.write(t + "/ext.nii", big, d, 4, 16, sform=ras, big=True, extension=48)
i32 = struct.pack("<%di" % (len(le) // 2), *struct.unpack("<%dh" % (len(le) // 2), le))
nw.write(t + "/i32.nii", i32, d, 8, 32, sform=ras)
nw.write(t + "/s.nii", le, d, 4, 16, sform=ras, slope=2.0, inter=-1000.0)
nw.write(t + "/f64.nii", f64, d, 64, 64, sform=ras)
nw.write(t + "/m.nii", le, d, 4, 16, sform=[[v / 1000 for v in r] for r in ras], units=1)   # in metres
# bad ones
nw.write(t + "/rgb.nii", le, d, 128, 24, sform=ras)
nw.write(t + "/4d.nii", le, d, 4, 16, sform=ras, dim0=4, dim4=3)
nw.write(t + "/zero.nii", le, d, 4, 16, sform=[[0, 0, 0, 0], [0, -sx, 0, 0], [0, 0, sz, 0]])
nw.write(t + "/shear.nii", le, d, 4, 16, sform=[[-sx, sx, 0, 0], [0, -sx, 0, 0], [0, 0, sz, 0]])
nw.write(t + "/pair.nii", le, d, 4, 16, sform=ras, magic=b"ni1\0")
nw.write(t + "/nans.nii", le, d, 4, 16, sform=[[float("nan"), 0, 0, 0], [0, -sx, 0, 0], [0, 0, sz, 0]])
open(t + "/cut.nii", "wb").write(open(t + "/a.nii", "rb").read()[:-1000])
nw.write(t + "/huge.nii.gz", b"", (2000, 2000, 2000), 4, 16, sform=ras, gz=True)   # 16 GB declared in 60 bytes
PY

field() { python3 -c "import json,sys; print(json.load(open(sys.argv[1])).get(sys.argv[2]))" "$T/body" "$1"; }
code=$(status POST "/isosurface?iso=226.5&dims=64,64,64&type=int16&spacing=$SX,$SX,$SZ&origin=-100,-120,-50" \
    -H 'Content-Type: application/octet-stream' --data-binary @"$CT")
cp "$T/body" "$T/ref.json"
check "the raw samples at the place the affines say: 201" '[ "$code" = 201 ]'
# same [REL [PLACE]]: the model in $T/body has the reference's triangles, volume (within REL; 1e-6:
# NIfTI-1's sform is float32; 1e-4 mirrored, whose cubes' ambiguous faces split the other way), bounds (1e-3 mm) where PLACE puts the reference's (id: the same;
# q0: the RAS grid as stored, x and y through -100, -120; q90: turned a quarter about z and k
# reversed; lh: y mirrored about -120), and is closed
same() {
    python3 -c "
import json, sys
a = json.load(open(sys.argv[1])); b = json.load(open(sys.argv[2])); rel = float(sys.argv[3]); place = sys.argv[4]
(x0, y0, z0), (x1, y1, z1) = b['bounds']
want = {'id': b['bounds'], 'q0': [[-x1 - 200, -y1 - 240, z0], [-x0 - 200, -y0 - 240, z1]],
        'q90': [[y0 + 20, -x1 - 220, -z1 - 100], [y1 + 20, -x0 - 220, -z0 - 100]],
        'lh': [[x0, -y1 - 240, z0], [x1, -y0 - 240, z1]]}[place]
ok = (a['triangles'] == b['triangles'] and abs(a['volume_mm3'] / b['volume_mm3'] - 1) < rel and a['boundary_edges'] == 0
      and all(abs(x - y) < 1e-3 for p, q in zip(a['bounds'], want) for x, y in zip(p, q)))
sys.exit(0 if ok else 1)" "$T/body" "$T/ref.json" "${1:-1e-6}" "${2:-id}"
}
code=$(status POST "/isosurface?iso=226.5" --data-binary @"$T/a.nii")
check "NIfTI-1 by its sform, posted without a type: the raw samples' mesh, in the same place" '[ "$code" = 201 ] && same'
code=$(status POST "/isosurface?iso=226.5" -H 'Content-Type: application/gzip' --data-binary @"$T/a2.nii.gz")
check "NIfTI-2, big-endian, gzip (application/gzip): the same (its sform double: to 1e-9)" '[ "$code" = 201 ] && same 1e-9'
code=$(status POST "/isosurface?iso=226.5&format=nifti" -H 'Content-Type: application/octet-stream' --data-binary @"$T/a.nii")
check "?format=nifti: the same" '[ "$code" = 201 ] && same'
code=$(status POST "/isosurface?iso=226.5" -H 'Content-Type: application/octet-stream' --data-binary @"$T/a.nii")
check "posted as application/octet-stream without ?dims: read as the NIfTI it is (not \"raw samples need dims\")" '[ "$code" = 201 ] && same'
code=$(status POST "/isosurface?iso=226.5" -H 'Content-Type: application/x-nifti' --data-binary @"$T/m.nii")
check "application/x-nifti, an affine in metres (xyzt_units): the same, in mm" '[ "$code" = 201 ] && same 1e-6'
code=$(status POST "/isosurface?iso=226.5" --data-binary @"$T/q.nii")
check "by its qform (the identity: the grid as stored in RAS+): the mesh where RAS puts it" '[ "$code" = 201 ] && same 1e-4 q0 && grep -q "\"origin\":\[-160" "$T/body"'
code=$(status POST "/isosurface?iso=226.5" --data-binary @"$T/q90.nii")
check "by a qform turned a quarter round z, qfac -1: the mesh turned and its k reversed" '[ "$code" = 201 ] && same 1e-4 q90'
code=$(status POST "/isosurface?iso=226.5" --data-binary @"$T/l.nii")
check "a left-handed sform (y reversed): closed, facing out, y mirrored about -120" '[ "$code" = 201 ] && same 1e-4 lh'
code=$(status POST "/isosurface?iso=226.5" --data-binary @"$T/nan.nii")
check "scl_slope and scl_inter NaN (nibabel's no scaling): the same" '[ "$code" = 201 ] && same'
code=$(status POST "/isosurface?iso=226.5" --data-binary @"$T/ext.nii")
check "big-endian, uncompressed, 48 bytes of extension before its samples (vox_offset 400): the same" '[ "$code" = 201 ] && same'
code=$(status POST "/isosurface?iso=226.5" --data-binary @"$T/i32.nii")
check "int32 samples (a label map's type): the same" '[ "$code" = 201 ] && same'
code=$(status POST "/isosurface?iso=-547" --data-binary @"$T/s.nii")
check "scl_slope 2, scl_inter -1000: iso in the scaled values (-547 is 226.5 stored) gives the same" '[ "$code" = 201 ] && same 1e-6'
code=$(status POST "/isosurface?iso=226.5" --data-binary @"$T/f64.nii")
check "float64 samples (datatype 64): the same" '[ "$code" = 201 ] && same 1e-6'

refused() { # refused FILE STATUS TEXT: the status, a problem whose detail holds TEXT
    want=$2 text=$3
    code=$(status POST "/isosurface?iso=226.5" --data-binary @"$T/$1")
    check "$1: $2, \"$3\"" '[ "$code" = "$want" ] && is_problem "$want" && grep -q "$text" "$T/body"'
}
refused rgb.nii 422 "datatype 128"
refused 4d.nii 422 "a series of volumes"
refused zero.nii 422 "column 0 is zero"
refused shear.nii 422 "shears the grid"
refused pair.nii 422 "pair"
refused nans.nii 422 "not finite"
refused cut.nii 422 "the file holds"
refused huge.nii.gz 422 "over the limit"
code=$(status POST "/isosurface?iso=226.5&dims=64,64,64" --data-binary @"$T/a.nii")
check "?dims with a NIfTI: 422 at ?dims (its header gives them)" '[ "$code" = 422 ] && grep -q "\"pointer\":\"?dims\"" "$T/body"'
code=$(status POST "/isosurface?iso=226.5&format=nifti" --data-binary @"$CT")
check "?format=nifti of raw samples: 400 saying what a NIfTI file begins with" '[ "$code" = 400 ] && grep -q "sizeof_hdr" "$T/body"'
SURFD_URL=$URL ./build/surfctl isosurface "$T/a2.nii.gz" --iso 226.5 -o "$T/a2.stl" >"$T/body" 2>/dev/null; rc=$?
check "surfctl isosurface FILE.nii.gz: the model, its mesh closed" '[ $rc -eq 0 ] && same 1e-9 && python3 tests/tools/stl_check.py "$T/a2.stl" - >/dev/null'
check "the Python client's isosurface(FILE.nii): the same" 'SURFD_URL=$URL PYTHONPATH=client/python python3 -c "
import json, surfd, sys
json.dump(surfd.Client(token=\"\").isosurface(sys.argv[1], iso=226.5), open(sys.argv[2], \"w\"))" "$T/a.nii" "$T/body" && same'
check "the daemon up after all of them" 'alive'
finish
