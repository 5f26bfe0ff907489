#!/bin/sh
# A contour model's patches (`surfd model --patches`) posted back to `surfd volume`, the figures path
# of POST /volume (issue 18): every shared contour file and RT Structure Set ROI closes as one solid
# with its model's volume, branchings (trimmed flat patches where tubes end and begin), holes and
# slivers between slices included; those over the request's caps are refused with the cap's message.
. "$(dirname "$0")/lib.inc"

# $1: a name for the check; the rest: surfd model's input and options. The patches' figures must be
# closed, none turned (where they are matched along their boundaries), the model's volume within 1e-6.
closes() {
    name=$1; shift
    $S model "$@" --patches "$T/p.json" >"$T/model" 2>"$T/err"
    mvol=$(python3 -c "import json,sys; print(json.load(open(sys.argv[1]))['volume_mm3'])" "$T/model" 2>/dev/null)
    $S volume "$T/p.json" >"$T/out" 2>"$T/err"; rc=$?
    check "$name: its patches close with its volume" '[ $rc -eq 0 ] && grep -q "\"closed\":true" "$T/out" && ! grep -q "\"surfaces_turned\":[1-9]" "$T/out" && python3 -c "import json,sys; v=json.load(open(sys.argv[1]))[\"volume_mm3\"]; sys.exit(abs(v/float(sys.argv[2])-1)>1e-6)" "$T/out" "$mvol"'
}

for f in synthetic_ellipsoid synthetic_bean dicompyler_heart dicompyler_tumor_bed eclipse_bladder eclipse_ptv \
         eclipse_rectum eclipse_femoral_head_lt; do
    closes "$f" "$C/$f.json"
done
for caps in flat slab dome; do
    closes "synthetic_torus_branching, $caps caps" "$C/synthetic_torus_branching.json" --caps "$caps"
done
check "the torus's branching planes are trimmed flat patches" 'python3 -c "import json,sys; o=json.load(open(sys.argv[1]))[\"objects\"]; sys.exit(sum(\"trim\" in x for x in o) != 4)" "$T/p.json"'
closes "synthetic_torus_branching.rtstruct.dcm" "$C/synthetic_torus_branching.rtstruct.dcm" --roi torus_branching
# (Breast: its ends are not star-shaped about their centroids, so their fans fold; its patches
# carry each end as a trimmed flat patch instead)
for roi in BODY Borders Breast Heart "Lt Lung" Nodes Scar "Tumor Bed" "Tumor Bed Block"; do
    closes "dicompyler RT Structure Set, $roi" "$C/dicompyler-core_example_rtss.dcm" --roi "$roi"
done
for roi in Bladder "Femoral Head Lt" "Femoral Head RT" PTV Rectum; do
    closes "Eclipse prostate phantom, $roi" "$C/slicerrt_EclipseProstatePhantom_RS.dcm" --roi "$roi"
done
# the lung's 50 059 patches are 3.6 M JSON values, read an object at a time (json_read_split); the
# Eclipse body's 19 278 (191 000 before the curves were redrawn on fewer knots: over the objects a
# scene may hold) close too
closes "dicompyler_lt_lung_multicontour" "$C/dicompyler_lt_lung_multicontour.json"
closes "eclipse_body" "$C/eclipse_body.json"
closes "Eclipse prostate phantom, BODY" "$C/slicerrt_EclipseProstatePhantom_RS.dcm" --roi BODY
# over the objects a scene may hold: refused with the cap's message (a model of 120 000 patches)
python3 -c "
import json
print(json.dumps({'objects': [{'type': 'bezier', 'degree': [1, 1], 'points': [[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]]}] * 120000}))" >"$T/big.json"
$S volume "$T/big.json" >/dev/null 2>"$T/err"; rc=$?
check "120 000 objects: over the request's caps, refused so" '[ $rc -eq 1 ] && grep -q "objects" "$T/err"'
checks_done
