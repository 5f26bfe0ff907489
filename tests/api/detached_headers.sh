#!/bin/sh
# A detached header and its data file over HTTP (issue 47: 6), as research tools export volumes
# (.nhdr + .raw, .mhd + .raw): POST /isosurface of the two as multipart/form-data (curl -F, either
# order) gives the mesh the offline CLI gives the header read beside its file, to the byte; surfctl
# and the Python client send the pair when given the header; a wrong pairing, a header alone, a third
# part and samples of the wrong length are 422s naming the part.
. "$(dirname "$0")/lib.inc"
V="${SURFD_DATA:-../shared/data}/volumes"
[ -f "$V/ct_head_crop64_int16.nhdr" ] || { bad "../shared/data/volumes not found"; checks_done; exit 1; }
H="$V/ct_head_crop64_int16.nhdr" M="$V/ct_head_crop64_int16.mhd" R="$V/ct_head_crop64_int16.raw"
field() { python3 -c "import json,sys; print(json.load(open(sys.argv[1])).get(sys.argv[2]))" "$T/body" "$1"; }
pointer() { python3 -c "import json,sys; print(json.load(open(sys.argv[1]))['errors'][0]['pointer'])" "$T/body"; }
"$SURFD_BIN" isosurface "$H" --iso 226.5 -o "$T/cli.stl" >/dev/null 2>&1
start_daemon "$T/d" || exit 1
mesh_is_cli() { [ "$(status GET "/models/$1/mesh?format=stl")" = 200 ] && cmp -s "$T/body" "$T/cli.stl"; }

code=$(status POST "/isosurface?iso=226.5" -F header=@"$H" -F data=@"$R"); id=$(field id)
check "curl -F header=@CT.nhdr -F data=@CT.raw: 201, the CLI's mesh of the .nhdr to the byte" '[ "$code" = 201 ] && [ -s "$T/cli.stl" ] && mesh_is_cli "$id"'
code=$(status POST "/isosurface?iso=226.5" -F data=@"$R" -F header=@"$M"); id=$(field id)
check "the data part first, a MetaImage .mhd: the same mesh" '[ "$code" = 201 ] && mesh_is_cli "$id"'
code=$(status POST "/isosurface?iso=226.5" -F header=@"$H" -F data=@"$V/ct_head_256x256x108_int16.raw")
check "a data part of another name than the header names: 422 at /parts/1, saying both" '[ "$code" = 422 ] && is_problem 422 && [ "$(pointer)" = /parts/1 ] && grep -q "ct_head_crop64_int16.raw" "$T/body" && grep -q "ct_head_256x256x108_int16.raw" "$T/body"'
head -c 1000 "$R" >"$T/ct_head_crop64_int16.raw"
code=$(status POST "/isosurface?iso=226.5" -F header=@"$H" -F data=@"$T/ct_head_crop64_int16.raw")
check "samples short of the header's sizes: 422 at the data part" '[ "$code" = 422 ] && [ "$(pointer)" = /parts/1 ] && grep -q "1000 bytes" "$T/body"'
code=$(status POST "/isosurface?iso=226.5" -F header=@"$H")
check "the header alone: 422 at /parts" '[ "$code" = 422 ] && [ "$(pointer)" = /parts ]'
code=$(status POST "/isosurface?iso=226.5" -F header=@"$H" -F data=@"$R" -F more=@"$R")
check "a third part: 422 at /parts" '[ "$code" = 422 ] && [ "$(pointer)" = /parts ] && grep -q "two parts, not 3" "$T/body"'
code=$(status POST "/isosurface?iso=226.5" -H 'Content-Type: application/x-nrrd' --data-binary @"$H")
check "the header posted alone as the body: 422 at its data file line, saying to post both parts" '[ "$code" = 422 ] && [ "$(pointer)" = "header line 12" ] && grep -q "multipart/form-data" "$T/body"'

SURFD_URL="$URL" ./build/surfctl isosurface "$M" --iso 226.5 -o "$T/ctl.stl" >"$T/body" 2>"$T/err"
check "surfctl isosurface CT.mhd: the pair sent, the same mesh" 'cmp -s "$T/ctl.stl" "$T/cli.stl"'
/usr/bin/python3 -c "
import sys; sys.path.insert(0, 'client/python'); import surfd
c = surfd.Client(sys.argv[1]); m = c.isosurface(sys.argv[2], iso=226.5)
open(sys.argv[3], 'wb').write(c.mesh(m['id']))" "$URL" "$H" "$T/py.stl" 2>"$T/err"
check "the Python client's isosurface('CT.nhdr'): the pair sent, the same mesh" 'cmp -s "$T/py.stl" "$T/cli.stl"'
finish
