#!/bin/sh
# DICOM series as a PACS sends them (issue 47: 4): the shared CT series compressed by dcmtk's own
# tools (dcmcrle, dcmcjpeg, dcmcjpls: RLE, JPEG lossless, JPEG-LS lossless) and as JPEG 2000 by
# OpenJPEG's opj_compress (tests/tools/dicom_write.py j2k), posted to /isosurface, each giving the
# mesh the uncompressed series gives; a slice whose JPEG-LS stream is damaged, or whose JPEG 2000
# stream is of another size, refused with its part, the daemon up.
. "$(dirname "$0")/lib.inc"
DD="${SURFD_DATA:-../shared/data}/volumes/dicom_ct_head_64x64x27"
[ -d "$DD" ] || { bad "../shared/data/volumes not found"; checks_done; exit 1; }
command -v dcmcjpls >/dev/null || { bad "dcmtk's tools are not installed (deploy/install-deps.sh installs them)"; checks_done; exit 1; }
start_daemon "$T/d" --threads 2 || exit 1

# post DIR: the series of DIR's files as multipart/form-data; the answer in $T/body
post() {
    parts=""; for f in "$1"/*; do parts="$parts -F slice=@$f"; done
    # shellcheck disable=SC2086
    status POST "/isosurface?iso=226.5" $parts
}
code=$(post "$DD")
cp "$T/body" "$T/plain.json"
check "the uncompressed series: 201" '[ "$code" = 201 ]'
same() { python3 -c "
import json, sys
a, b = json.load(open(sys.argv[1])), json.load(open(sys.argv[2]))
sys.exit(0 if a['triangles'] == b['triangles'] and a['volume_mm3'] == b['volume_mm3'] and a['bounds'] == b['bounds'] else 1)" "$T/body" "$T/plain.json"; }
for tool in dcmcrle dcmcjpeg dcmcjpls; do
    mkdir -p "$T/$tool"
    for f in "$DD"/*; do "$tool" "$f" "$T/$tool/$(basename "$f")" || bad "$tool $f"; done
    ts=$(dcmdump "$T/$tool/$(ls "$T/$tool" | head -n 1)" 2>/dev/null | sed -n 's/.*(0002,0010) UI =\([A-Za-z0-9:-]*\).*/\1/p')
    code=$(post "$T/$tool")
    check "$ts ($tool): the same mesh as the uncompressed series, to the bit" '[ "$code" = 201 ] && same'
done
# JPEG 2000 (Debian's DCMTK has no codec: OpenJPEG through api/j2k.c), one tile and 32 x 32 tiles
if /usr/bin/python3 -c "import pydicom" 2>/dev/null && command -v opj_compress >/dev/null; then
    /usr/bin/python3 tests/tools/dicom_write.py j2k "$DD" "$T/j2k"
    code=$(post "$T/j2k")
    check "JPEG 2000 lossless (opj_compress): the same mesh as the uncompressed series, to the bit" '[ "$code" = 201 ] && same'
    /usr/bin/python3 tests/tools/dicom_write.py j2k "$DD" "$T/j2k_tiled" tiles
    code=$(post "$T/j2k_tiled")
    check "... in 32 x 32 tiles: the same mesh" '[ "$code" = 201 ] && same'
    cp "$T/j2k"/* "$T/j2k_tiled/"
    first=$(ls "$T/j2k_tiled" | head -n 1)
    python3 -c "
import sys
d = bytearray(open(sys.argv[1], 'rb').read()); i = d.rfind(b'\xff\x4f\xff\x51')
d[i + 8:i + 12] = (65).to_bytes(4, 'big')  # Xsiz: 65 columns, where the slice has 64
open(sys.argv[1], 'wb').write(d)" "$T/j2k_tiled/$first"
    code=$(post "$T/j2k_tiled")
    check "a JPEG 2000 stream of another size than its slice's Columns: 422 at its part, saying both" '[ "$code" = 422 ] && grep -q "not the frame.s 64 x 64" "$T/body" && grep -q "\"pointer\":\"/parts/" "$T/body"'
else
    bad "python3-pydicom or opj_compress (libopenjp2-tools) is missing (deploy/install-deps.sh installs them)"
fi
mkdir -p "$T/bad"
cp "$T/dcmcjpls"/* "$T/bad/"
first=$(ls "$T/bad" | head -n 1)
python3 -c "
import sys
d = bytearray(open(sys.argv[1], 'rb').read()); i = d.rfind(b'\xff\xd8')
for k in range(i + 200, min(len(d) - 10, i + 1200), 7): d[k] ^= 0x5a
open(sys.argv[1], 'wb').write(d)" "$T/bad/$first"
code=$(post "$T/bad")
check "a slice whose JPEG-LS stream is damaged: 422 at its part, saying it does not decode" '[ "$code" = 422 ] && is_problem 422 && grep -q "does not decode" "$T/body" && grep -q "\"pointer\":\"/parts/" "$T/body"'
check "the daemon up" 'alive'
finish
