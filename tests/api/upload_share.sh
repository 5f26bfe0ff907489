#!/bin/sh
# Issue 48, 8a: each owner's uploads have a share of the data dir (upload-share): the streamed
# bodies arriving and those kept for the owner's jobs not yet ended. An upload that would go over
# is refused from its headers (429, or 413 when it alone is larger than a share) while another
# owner's goes on; a body without a length is counted as it arrives; an ended job's body is
# removed, so the share frees itself as the owner's jobs run.
. "$(dirname "$0")/lib.inc"

RAW='Content-Type: application/octet-stream'
printf 'alice:alice-secret-token\nbob:bob-secret-token\n' >"$T/tokens"; chmod 600 "$T/tokens"
A='Authorization: Bearer alice-secret-token'
B='Authorization: Bearer bob-secret-token'
field() { python3 -c "import json,sys; print(json.load(open(sys.argv[1])).get(sys.argv[2], ''))" "$T/body" "$1"; }
# a ball in 128^3 uint8 samples: 2 MB, an isosurface that runs in a moment
python3 -c "
import sys
n = 128
row = lambda y, z: bytes(200 if (x-64)**2 + (y-64)**2 + (z-64)**2 < 900 else 0 for x in range(n))
sys.stdout.buffer.write(b''.join(row(y, z) for z in range(n) for y in range(n)))" >"$T/ball.raw"
head -c 4000000 /dev/zero >"$T/big.raw"
VOL="/isosurface?dims=128,128,128&type=uint8&iso=100"
# until_state ID STATE: alice's job reaches STATE within a minute
until_state() {
    for _ in $(seq 600); do
        curl -s -H "$A" "$URL/jobs/$1" | grep -q "\"state\":\"$2\"" && return 0
        sleep 0.1
    done
    return 1
}
uploads() { find "$T/d/uploads" -type f ! -name 'tmp-*' | wc -l; }

start_daemon "$T/d" --token-file "$T/tokens" --threads 1 --upload-share 3000000 || exit 1
# the one worker busy with a long render: alice's upload waits queued, holding its bytes
status POST "/render?width=400&height=400&method=montecarlo" -H "$A" -H 'Prefer: respond-async' \
    -H 'Content-Type: application/json' --data-binary @"$D/teacup.json" >/dev/null
busy=$(field id)
code=$(status POST "$VOL" -H "$A" -H "$RAW" -H 'Prefer: respond-async' --data-binary @"$T/ball.raw")
check "alice's first 2 MB upload (share 3 MB): 202, queued behind the render" '[ "$code" = 202 ]'
queued=$(field id)
sent=$(curl -s -o "$T/body" -D "$T/hdr" -w '%{http_code} %{size_upload}' -H "$A" -H "$RAW" -H 'Expect: 100-continue' \
    --data-binary @"$T/ball.raw" "$URL$VOL")
check "her second: 429 naming upload-share and what her uploads hold, with Retry-After" \
    '[ "${sent% *}" = 429 ] && is_problem 429 && grep -q "upload-share, 3000000 bytes" "$T/body" && grep -q "hold 2097152 of" "$T/body" && [ -n "$(header Retry-After)" ]'
check "... decided from its headers: not a byte of the body sent, no file begun" '[ "${sent#* }" = 0 ] && [ "$(find "$T/d/uploads" -name "tmp-*" | wc -l)" = 0 ]'
code=$(status POST "$VOL" -H "$B" -H "$RAW" -H 'Prefer: respond-async' --data-binary @"$T/ball.raw")
check "bob's 2 MB upload meanwhile: 202 (his share is his own)" '[ "$code" = 202 ]'
code=$(status POST "/isosurface?dims=200,200,100&type=uint8&iso=1" -H "$A" -H "$RAW" --data-binary @"$T/big.raw")
check "an upload larger than a whole share (4 MB): 413 naming upload-share" '[ "$code" = 413 ] && is_problem 413 && grep -q "larger than one owner.s share of the data dir (upload-share" "$T/body"'
code=$(status POST "$VOL" -H "$A" -H "$RAW" -H 'Transfer-Encoding: chunked' --data-binary @"$T/ball.raw")
check "a chunked upload, without a length: counted as it arrives, 429 when it goes over" '[ "$code" = 429 ] && is_problem 429 && grep -q "upload-share" "$T/body"'
check "... and its file is gone" '[ "$(find "$T/d/uploads" -name "tmp-*" | wc -l)" = 0 ]'
check "the stored bodies of the two queued jobs" '[ "$(uploads)" = 2 ]'

# ---- the share frees itself as her jobs end ----------------------------------------------------
check "the render cancelled" '[ "$(status POST "/jobs/$busy/cancel" -H "$A")" = 202 ] && until_state "$busy" cancelled'
check "her queued upload runs to its end" 'until_state "$queued" succeeded'
for _ in $(seq 30); do
    code=$(status POST "$VOL" -H "$A" -H "$RAW" --data-binary @"$T/ball.raw")
    [ "$code" = 429 ] || break
    sleep 0.5
done
check "... and her next 2 MB upload is taken (within the keeper's few seconds): 201" '[ "$code" = 201 ]'
stop_daemon
start_daemon "$T/d" --token-file "$T/tokens" --threads 1 --upload-share 3000000 || exit 1
check "an ended job's body is removed (here by the start's sweep; else by the minute's prune)" '[ "$(uploads)" = 0 ]'

# ---- the default: a quarter of the data dir's file system ------------------------------------
stop_daemon
start_daemon "$T/d" --token-file "$T/tokens" --threads 1 --log-level debug || exit 1
code=$(status POST "$VOL" -H "$A" -H "$RAW" --data-binary @"$T/ball.raw")
check "without upload-share, a 2 MB upload is taken: 201" '[ "$code" = 201 ]'
finish
