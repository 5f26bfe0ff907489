#!/bin/sh
# client/python/surfd.py against the real daemon with a token (tests/api/python_client.py).
. "$(dirname "$0")/lib.inc"
[ -f "${SURFD_DATA:-../shared/data}/contours/synthetic_ellipsoid.json" ] || { bad "../shared/data not found"; finish; }
printf 'py:tok-python\n' >"$T/tokens"; chmod 600 "$T/tokens"
start_daemon "$T/d" --token-file "$T/tokens" --sync-wait 5 || exit 1
SURFD_URL="$URL" SURFD_TOKEN=tok-python T="$T" python3 tests/api/python_client.py >"$T/py.out" 2>&1
while IFS= read -r line; do
    case $line in PASS:*) ok ;; FAIL:*) bad "${line#FAIL: }" ;; esac
done <"$T/py.out"
grep -q "^[0-9]* failed$" "$T/py.out" || { bad "python_client.py did not finish:"; tail -15 "$T/py.out"; }
finish
