#!/bin/sh
# `surfd isosurface` on the files a user has: detached headers (NRRD's .nhdr, MetaImage's .mhd,
# as the shared volumes and most tools' exports come) read with their data file beside them, the
# same mesh as the raw samples with the layout given; a data file that is not there is a clear
# failure.
. "$(dirname "$0")/lib.inc"
V="${SURFD_DATA:-../shared/data}/volumes"
tri() { sed -n 's/.*"triangles":\([0-9]*\).*/\1/p' "$1"; }

$S isosurface "$V/ct_head_crop64_int16.raw" --dims 64,64,64 --type int16 --spacing 0.957031,0.957031,1.5 --iso 226.5 \
    >"$T/raw" 2>"$T/err"
check "raw samples with their layout" '[ $? -eq 0 ] && [ "$(tri "$T/raw")" -gt 1000 ]'
for h in nhdr mhd; do
    $S isosurface "$V/ct_head_crop64_int16.$h" --iso 226.5 >"$T/$h" 2>"$T/err"
    check ".$h with its data file beside it: the raw's mesh" '[ $? -eq 0 ] && [ "$(tri "$T/$h")" = "$(tri "$T/raw")" ]'
done
# the header copied elsewhere: its data file is not beside it
for h in nhdr mhd; do
    cp "$V/ct_head_crop64_int16.$h" "$T/moved.$h"
    $S isosurface "$T/moved.$h" --iso 226.5 >/dev/null 2>"$T/err"; rc=$?
    check ".$h without its data file: a clear failure" '[ $rc -eq 1 ] && grep -q "ct_head_crop64_int16.raw" "$T/err"'
done
# a detached NRRD with a blank line after its header, and its fields after the data file line
printf 'NRRD0004\ntype: uint8\ndimension: 3\ndata file: b.raw\nsizes: 4 4 4\nencoding: raw\n\n' >"$T/b.nhdr"
python3 -c "import sys; sys.stdout.buffer.write(bytes(200 if 0 < x < 3 and 0 < y < 3 and 0 < z < 3 else 0 for z in range(4) for y in range(4) for x in range(4)))" >"$T/b.raw"
$S isosurface "$T/b.nhdr" --iso 100 >"$T/out" 2>"$T/err"
check "a detached NRRD's fields after its data file line" '[ $? -eq 0 ] && grep -q "\"closed\":true" "$T/out" && [ "$(tri "$T/out")" -gt 0 ]'
# a MetaImage header that starts with NDims, its data file by a path relative to the header
mkdir -p "$T/d"; cp "$T/b.raw" "$T/d/c.raw"
printf 'NDims = 3\nDimSize = 4 4 4\nElementType = MET_UCHAR\nElementDataFile = d/c.raw\n' >"$T/c.mhd"
$S isosurface "$T/c.mhd" --iso 100 >"$T/out2" 2>"$T/err"
check "a .mhd starting with NDims: the same mesh as the NRRD's" '[ $? -eq 0 ] && [ "$(tri "$T/out2")" = "$(tri "$T/out")" ]'
# headers whose last line has no newline (editors leave it off): the same meshes
printf 'NDims = 3\nDimSize = 4 4 4\nElementType = MET_UCHAR\nElementDataFile = d/c.raw' >"$T/e.mhd"
$S isosurface "$T/e.mhd" --iso 100 >"$T/out3" 2>"$T/err"
check "a .mhd without a newline after its data file line" '[ $? -eq 0 ] && [ "$(tri "$T/out3")" = "$(tri "$T/out")" ]'
printf 'NRRD0004\ntype: uint8\ndimension: 3\ndata file: b.raw\nsizes: 4 4 4\nencoding: raw' >"$T/e.nhdr"
$S isosurface "$T/e.nhdr" --iso 100 >"$T/out4" 2>"$T/err"
check "a .nhdr without a newline or a blank line after its last field" '[ $? -eq 0 ] && [ "$(tri "$T/out4")" = "$(tri "$T/out")" ]'
# a multi-file NRRD is not read: volume_read's own answer, naming the line
printf 'NRRD0004\ntype: uint8\ndimension: 3\nsizes: 4 4 4\nencoding: raw\ndata file: LIST\nb.raw\n' >"$T/l.nhdr"
$S isosurface "$T/l.nhdr" --iso 100 >/dev/null 2>"$T/err"; rc=$?
check "a multi-file NRRD: refused with its header line" '[ $rc -eq 1 ] && grep -q "header line 6" "$T/err"'
checks_done
