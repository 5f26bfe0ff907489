#!/bin/sh
# The web page at / in a real browser (issues 19, 46): tests/web/page.mjs against the real daemon, open
# and then with a token required; each downloaded STL is checked closed with the model's volume.
# In the open run surfd is also a DICOM node: a real PACS (Orthanc: tests/tools/orthanc.sh) sends it
# the CT, the page opens the series' slices and sends a model back, found in the PACS after.
# The 3D view's WebGL runs on Chromium's SwiftShader (software), so no GPU is needed.
# Needs Debian's chromium (deploy/install-deps.sh) and playwright-core from npm, installed into
# build/npm on first use. Screenshots stay in build/web-shots for a person to look at.
. "$(dirname "$0")/../api/lib.inc"
. tests/tools/orthanc.sh
PLAYWRIGHT_VERSION=1.65.1
N=build/npm
SHOTS=build/web-shots
C="${SURFD_DATA:-../shared/data}/contours/synthetic_ellipsoid.json"
RS="${SURFD_DATA:-../shared/data}/contours/dicompyler-core_example_rtss.dcm" # 9 ROIs with contours, in their colours
DD="${SURFD_DATA:-../shared/data}/volumes/dicom_ct_head_64x64x27" # a CT series, sent to surfd by a real PACS (Orthanc)
mkdir -p "$SHOTS"
rm -f "$SHOTS"/model-*.id
if [ ! -d "$N/node_modules/playwright-core" ]; then
    mkdir -p "$N"
    npm install --silent --no-audit --no-fund --prefix "$N" "playwright-core@$PLAYWRIGHT_VERSION" >"$N/playwright.log" 2>&1 ||
        bad "npm could not install playwright-core@$PLAYWRIGHT_VERSION"
fi
[ -x /usr/bin/chromium ] || bad "no /usr/bin/chromium (deploy/install-deps.sh installs it)"
[ -f "$C" ] && [ -f "$RS" ] || bad "../shared/data/contours not found"
run_page() { # run_page TAG [TOKEN]
    tag=$1
    NODE_PATH="$N/node_modules" URL="$URL" CONTOURS="$C" RTSS="$RS" SHOTS="$SHOTS" TOKEN="${2:-}" SERIES="${SERIES:-}" \
        DATA="${SURFD_DATA:-../shared/data}" \
        node tests/web/page.mjs >"$T/page.out" 2>&1
    while IFS= read -r line; do
        case $line in PASS:*) ok ;; FAIL:*) bad "${line#FAIL: }" ;; esac
    done <"$T/page.out"
    grep -q "^PASS:\|^FAIL:" "$T/page.out" || { bad "page.mjs did not run:"; tail -5 "$T/page.out"; }
    code=$(status GET "/models/$(cat "$SHOTS/model-$tag.id" 2>/dev/null)" ${2:+-H "Authorization: Bearer $2"})
    vol=$(python3 -c "import json,sys; print(json.load(open(sys.argv[1]))['volume_mm3'])" "$T/body" 2>/dev/null)
    check "the page's STL ($tag) is closed, with the model's volume" 'python3 tests/tools/stl_check.py "$SHOTS/model-$tag.stl" "$vol" >/dev/null'
    check "the page's RT Structure Set ($tag) is DICOM" '[ "$(dd if="$SHOTS/model-$tag.dcm" bs=1 skip=128 count=4 2>/dev/null)" = DICM ]'
}
if [ "$fail" -eq 0 ]; then
    # the open run: surfd a DICOM node that a real PACS (Orthanc) sends the CT to, and that sends
    # models back to it (its DICOMweb): the page lists the series, opens its slices and sends a model
    [ -x "$ORTHANC_BIN" ] || bad "no Orthanc (deploy/install-deps.sh installs orthanc and orthanc-dicomweb)"
    DP=$(orthanc_free_port)
    if [ -x "$ORTHANC_BIN" ] && orthanc_start "$T/orthanc" "SURFD@127.0.0.1:$DP"; then
        orthanc_upload "$DD"/*.dcm >"$T/ids" || bad "Orthanc refused the CT"
        echo "ORTHANC 127.0.0.1 $ORTHANC_DICOM_PORT" >"$T/peers"
        # (--drain-timeout 1: a render the page let go of runs on, and the stop would wait for it)
        # shellcheck disable=SC2046 # (the instances' ids, one a word)
        start_daemon "$T/open" --threads 2 --drain-timeout 1 --dicom-listen "$DP" --dicom-peers "$T/peers" --series-idle 1 \
            --pacs "orthanc=$ORTHANC_DICOMWEB" --pacs-credentials "orthanc=$ORTHANC_CREDENTIALS" &&
            { orthanc_send surfd $(cat "$T/ids") >/dev/null || bad "Orthanc could not send the CT to surfd"; } &&
            SERIES=$(curl -s "$URL/series" | python3 -c "import json,sys; print(json.load(sys.stdin)['series'][0]['uid'])") &&
            run_page open
        n=$(orthanc_curl -s /statistics | python3 -c "import json,sys; print(json.load(sys.stdin)['CountInstances'])")
        check "the model the page sent is in the PACS (Orthanc: the CT's 27 instances and one more)" '[ "$n" = 28 ]'
    fi
    stop_daemon
    printf 'web:%s\n' "s3cret-web-token" >"$T/tokens"
    chmod 600 "$T/tokens"
    SERIES="" # (the token run: no DICOM node, no PACS)
    start_daemon "$T/tok" --threads 2 --token-file "$T/tokens" && run_page token s3cret-web-token
fi
finish
