#!/bin/sh
# Black-box tests of surfd serve: the routes of API.md as curl users drive them, every error kind
# as problem+json with the daemon still up, jobs (sync, async, cancel, ETag), the bounded queue,
# kill -9 recovery, SIGTERM drain, bearer tokens, the public-address refusal, TLS, 32 clients.
. "$(dirname "$0")/lib.inc"

# ---- basics ---------------------------------------------------------------------------------
start_daemon "$T/d1" --threads 2 --max-body 4194304 || exit 1
check "livez" '[ "$(status GET /livez)" = 200 ]'
check "readyz" '[ "$(status GET /readyz)" = 200 ]'
check "version" '[ "$(status GET /version)" = 200 ] && grep -q "\"name\":\"surfd\"" "$T/body"'
check "openapi" '[ "$(status GET /openapi.yaml)" = 200 ] && grep -q "^openapi: 3" "$T/body" && grep -q "/jobs/{id}/result" "$T/body"'

# ---- sync render ----------------------------------------------------------------------------
check "the image writers are not loaded before the first image" '! grep -q libOpenImageIO /proc/$PID/maps'
code=$(status POST "/render?width=128&height=96" -H 'Content-Type: application/json' --data-binary @"$D/teapot.json")
check "... nor after a PNG (api/png.c writes it)" '! grep -q libOpenImageIO /proc/$PID/maps'
check "sync render 200 png" '[ "$code" = 200 ] && [ "$(header Content-Type)" = image/png ] && [ "$(head -c 4 "$T/body" | od -An -tx1 | tr -d " \n")" = 89504e47 ]'
check "sync render headers" '[ -n "$(header X-Job-Id)" ] && [ -n "$(header X-Render-Ms)" ] && [ -n "$(header X-Rays)" ] && [ -n "$(header ETag)" ]'
code=$(status POST "/render?width=64&height=48&output=exr" -H 'Content-Type: model/x-bpt' --data-binary @"$D/teacup.bpt")
check "bpt body, exr out" '[ "$code" = 200 ] && [ "$(header Content-Type)" = image/x-exr ]'
check "... and the image writers are loaded after an EXR" 'grep -q libOpenImageIO /proc/$PID/maps'
code=$(status POST "/render?format=nurbs&width=64&height=48" --data-binary @"$D/duck1.nurbs")
check "?format=nurbs, curl -d default type" '[ "$code" = 200 ]'
code=$(status POST "/render?width=64&height=48" -H 'Content-Type: text/plain' --data-binary @"$D/duck3.nurbs")
check "text/plain sniffed" '[ "$code" = 200 ]'

# ---- async, job resource, result, ETag ------------------------------------------------------
code=$(status POST "/render?width=96&height=64" -H 'Prefer: respond-async' -H 'Content-Type: application/json' --data-binary @"$D/teaspoon.json")
id=$(header X-Job-Id)
check "async 202 + Location" '[ "$code" = 202 ] && [ "$(header Location)" = "/jobs/$id" ] && grep -q "\"kind\":\"render\"" "$T/body"'
check "job succeeds" 'wait_state "$id" succeeded'
check "job resource" '[ "$(status GET /jobs/$id)" = 200 ] && grep -q "\"progress\":1" "$T/body" && grep -q "\"finished\":\"20" "$T/body"'
code=$(status GET "/jobs/$id/result")
etag=$(header ETag)
check "result 200" '[ "$code" = 200 ] && [ "$(header Content-Type)" = image/png ] && [ -n "$etag" ]'
check "result 304" '[ "$(status GET /jobs/$id/result -H "If-None-Match: $etag")" = 304 ]'
check "job list" '[ "$(status GET "/jobs?state=succeeded")" = 200 ] && grep -q "$id" "$T/body"'
code=$(status POST "/render?width=64&height=48" -H 'Prefer: wait=0' -H 'Content-Type: application/json' --data-binary @"$D/teapot.json")
check "Prefer: wait=0 gives 202" '[ "$code" = 202 ]'

# ---- every error kind, and the daemon stays up ------------------------------------------------
code=$(status POST /render -H 'Content-Type: application/json' --data-binary '{"objects": [')
check "400 malformed" '[ "$code" = 400 ] && is_problem 400'
head -c 5000000 /dev/zero | tr '\0' ' ' >"$T/big"
code=$(status POST /render -H 'Content-Type: application/json' --data-binary @"$T/big")
check "413 from Content-Length" '[ "$code" = 413 ] && is_problem 413'
code=$(status POST /render -H 'Content-Type: application/json' -H 'Transfer-Encoding: chunked' --data-binary @"$T/big")
check "413 chunked" '[ "$code" = 413 ] && is_problem 413'
check "415" '[ "$(status POST /render -H "Content-Type: image/png" --data-binary x)" = 415 ] && is_problem 415'
code=$(status POST /render -H 'Content-Type: application/json' --data-binary '{"objects":[{"type":"nurbs","degree":[1,1],"size":[2,2],"knots_u":[0,0,1,1],"knots_v":[0,0,1,1],"points":[[0,0,0],[1,0,0],[0,1,0],[1,1,1]],"weights":[1,1,-1,1]}]}')
check "422 with pointer" '[ "$code" = 422 ] && is_problem 422 && grep -q "\"pointer\":\"/objects/0/weights/2\"" "$T/body"'
code=$(status POST "/render?width=0" -H 'Content-Type: application/json' --data-binary @"$D/teapot.json")
check "422 query option" '[ "$code" = 422 ] && grep -q "\"pointer\":\"?width\"" "$T/body"'
code=$(status POST "/render?bogus=1" -H 'Content-Type: application/json' --data-binary @"$D/teapot.json")
check "422 unknown option" '[ "$code" = 422 ] && grep -q "?bogus" "$T/body"'
code=$(status POST /render -H 'Content-Type: application/json' --data-binary '{"image":{"width":16384,"height":16384},"objects":[{"degree":[1,1],"points":[[0,0,0],[1,0,0],[0,1,0],[1,1,1]]}]}')
check "422 image too large" '[ "$code" = 422 ] && grep -q "\"pointer\":\"/image\"" "$T/body"'
check "404 job" '[ "$(status GET /jobs/0123456789abcdef0123456789abcdef)" = 404 ] && is_problem 404'
check "404 bad id" '[ "$(status GET /jobs/..%2f..%2fetc)" = 404 ]'
check "404 route" '[ "$(status GET /nowhere)" = 404 ] && is_problem 404'
check "405" '[ "$(status GET /render)" = 405 ] && is_problem 405'
check "/isosurface is built: samples without ?iso are a 422 naming it" '[ "$(status POST /isosurface -H "Content-Type: application/octet-stream" -d "xxxxxxxx")" = 422 ] && grep -q "?iso" "$T/body"'
check "... and {} is an FRep request without its tree: a 422 naming /bounds" '[ "$(status POST /isosurface -d "{}")" = 422 ] && grep -q "\"pointer\":\"/bounds\"" "$T/body"'

# ---- POST /volume (contours) --------------------------------------------------------------
C="${SURFD_DATA:-../shared/data}/contours"
code=$(status POST /volume -H 'Content-Type: application/json' --data-binary @"$C/synthetic_ellipsoid.json")
check "volume 200 with figures" '[ "$code" = 200 ] && [ "$(header Content-Type)" = application/json ] && grep -q "\"volume_mm3\":123" "$T/body" && [ -n "$(header X-Job-Id)" ]'
code=$(status POST /volume -H 'Prefer: respond-async' -H 'Content-Type: application/json' --data-binary @"$C/eclipse_ptv.json")
vid=$(header X-Job-Id)
check "volume async" '[ "$code" = 202 ] && wait_state "$vid" succeeded && [ "$(status GET /jobs/$vid)" = 200 ] && grep -q "\"kind\":\"volume\"" "$T/body"'
code=$(status POST /volume -H 'Content-Type: application/json' --data-binary '{"slices":[{"z":0,"points":[[0,0],[1,1],[1,0],[0,1]]},{"z":1,"points":[[0,0],[1,0],[0,1]]}]}')
check "volume 422 crossing contour" '[ "$code" = 422 ] && grep -q "\"pointer\":\"/slices/0/points\"" "$T/body"'
code=$(status POST "/volume?roi=Heart" -H 'Content-Type: application/dicom' --data-binary @"$C/dicompyler-core_example_rtss.dcm")
check "volume from RTSTRUCT ?roi" '[ "$code" = 200 ] && grep -q "\"volume_mm3\":434477.95" "$T/body" && grep -q "\"name\":\"Heart\"" "$T/body"'
code=$(status POST /volume -H 'Content-Type: application/dicom' --data-binary @"$C/slicerrt_EclipseProstatePhantom_RS.dcm")
check "volume from RTSTRUCT, every ROI" '[ "$code" = 200 ] && grep -q "\"models\":\[" "$T/body" && grep -q "\"name\":\"Rectum\"" "$T/body"'
check "volume 400 not DICOM" '[ "$(status POST /volume -H "Content-Type: application/dicom" --data-binary x)" = 400 ] && is_problem 400'
check "volume 422 unknown ROI" '[ "$(status POST "/volume?roi=Nope" -H "Content-Type: application/dicom" --data-binary @"$C/dicompyler-core_example_rtss.dcm")" = 422 ] && grep -q "\"pointer\":\"?roi\"" "$T/body"'
check "volume 415" '[ "$(status POST /volume -H "Content-Type: image/png" --data-binary x)" = 415 ]'
check "volume 400" '[ "$(status POST /volume -H "Content-Type: application/json" --data-binary "{")" = 400 ]'
check "daemon up after errors" 'alive'

# ---- cancel ---------------------------------------------------------------------------------
code=$(status POST "/render?width=2048&height=2048&method=bvh" -H 'Prefer: respond-async' -H 'Content-Type: application/json' --data-binary @"$D/teapot.json")
id=$(header X-Job-Id)
wait_state "$id" running 10
check "cancel 202" '[ "$(status POST /jobs/$id/cancel)" = 202 ]'
check "cancelled" 'wait_state "$id" cancelled 20'
check "cancelled result 409" '[ "$(status GET /jobs/$id/result)" = 409 ] && is_problem 409'
check "cancel ended job 409" '[ "$(status POST /jobs/$id/cancel)" = 409 ]'

# ---- metrics ----------------------------------------------------------------------------------
check "metrics" '[ "$(status GET /metrics)" = 200 ] && grep -q "^surfd_jobs_ended_total{state=\"cancelled\"} 1" "$T/body" && grep -q "^surfd_render_seconds_count [1-9]" "$T/body" && grep -q "^surfd_http_requests_total{status=\"422\"} [1-9]" "$T/body" && grep -q "^surfd_uptime_seconds" "$T/body" && grep -q "^surfd_rays_per_second" "$T/body"'
check "access log has no query or token" 'grep -q "access 127.0.0.1 POST /render 422" "$T/daemon.log" && ! grep -q "width=0" "$T/daemon.log"'

# ---- 32 clients at once ---------------------------------------------------------------------
pids=""
for k in $(seq 32); do
    curl -s -o /dev/null -w '%{http_code}\n' -H 'Content-Type: application/json' --data-binary @"$D/teaspoon.json" \
        "$URL/render?width=48&height=32" >"$T/c$k" &
    pids="$pids $!"
done
wait $pids # not a bare wait: that would wait for the daemon too
codes=$(cat "$T"/c* | sort | uniq -c | tr -s ' ')
check "32 clients: 200 or 429 only, most 200" 'echo "$codes" | grep -vqE "^ ?[0-9]+ (200|429)$" && false || [ "$(cat "$T"/c* | grep -c 200)" -ge 16 ]'
check "daemon up after 32 clients" 'alive'
stop_daemon

# ---- bounded queue: 429 + Retry-After -----------------------------------------------------------
start_daemon "$T/d2" --threads 1 --queue-max 1 || exit 1
for k in 1 2 3; do
    status POST "/render?width=1024&height=1024&method=bvh" -H 'Prefer: respond-async' -H 'Content-Type: application/json' --data-binary @"$D/teapot.json" >"$T/q$k"
    cp "$T/hdr" "$T/qh$k"
done
check "429 when full" 'grep -q 429 "$T/q3" && grep -qi "^Retry-After: " "$T/qh3"'
stop_daemon

# ---- kill -9 and restart: nothing accepted is lost --------------------------------------------
start_daemon "$T/d3" --threads 1 || exit 1
ids=""
for k in 1 2 3; do
    status POST "/render?width=512&height=512&method=bvh" -H 'Prefer: respond-async' -H 'Content-Type: application/json' --data-binary @"$D/teapot.json" >/dev/null
    ids="$ids $(header X-Job-Id)"
done
kill -9 "$PID"; wait "$PID" 2>/dev/null; PID=""
start_daemon "$T/d3" --threads 2 || exit 1
for id in $ids; do
    check "recovered $id" 'wait_state "$id" succeeded 30 && [ "$(status GET /jobs/$id/result)" = 200 ]'
done
check "recovery logged" 'grep -q "recovered job" "$T/daemon.log"'

# ---- SIGTERM: drain, keep queued jobs, exit 0 -------------------------------------------------
status POST "/render?width=1024&height=1024&method=bvh" -H 'Prefer: respond-async' -H 'Content-Type: application/json' --data-binary @"$D/teapot.json" >/dev/null
kill -TERM "$PID"; wait "$PID"; rc=$?; PID=""
check "SIGTERM exits 0" '[ "$rc" = 0 ] && grep -q "draining" "$T/daemon.log"'

# ---- bearer tokens ----------------------------------------------------------------------------
printf '# tokens\ns3cret-token-one\nanother-token\n' >"$T/tokens"; chmod 600 "$T/tokens"
start_daemon "$T/d4" --token-file "$T/tokens" || exit 1
check "401 without token" '[ "$(status GET /jobs)" = 401 ] && is_problem 401 && header WWW-Authenticate | grep -q Bearer'
check "401 wrong token" '[ "$(status GET /jobs -H "Authorization: Bearer s3cret-token-onE")" = 401 ]'
check "200 right token" '[ "$(status GET /jobs -H "Authorization: Bearer another-token")" = 200 ]'
check "livez needs no token" '[ "$(status GET /livez)" = 200 ]'
check "token never logged" '! grep -q "s3cret" "$T/daemon.log"'
stop_daemon

# ---- refusing an unauthenticated public listener -------------------------------------------
$S serve --listen 0.0.0.0:0 --data-dir "$T/d5" >"$T/refuse.log" 2>&1; rc=$?
check "public listener without tokens refused" '[ "$rc" = 2 ] && grep -q "refusing to listen" "$T/refuse.log"'
$S serve --listen 0.0.0.0:0 --data-dir "$T/d5" --bogus 1 >"$T/refuse.log" 2>&1; rc=$?
check "unknown setting refused" '[ "$rc" = 2 ] && grep -q "unknown setting" "$T/refuse.log"'
printf 'threads = 2\nqueue-max = 0\n' >"$T/bad.conf"
$S serve --config "$T/bad.conf" >"$T/refuse.log" 2>&1; rc=$?
check "config file checked" '[ "$rc" = 2 ] && grep -q "bad.conf:2: queue-max" "$T/refuse.log"'
mkdir -p "$T/alone" && cp "$S" "$T/alone/surfd"
"$T/alone/surfd" serve --listen 127.0.0.1:0 --data-dir "$T/d5" >"$T/refuse.log" 2>&1; rc=$?
check "without its image library a server says so at start" '[ "$rc" = 1 ] && grep -q "libsurfd-image.so) are in neither $T/alone/libsurfd-image.so" "$T/refuse.log"'

# ---- a shared budget for request bodies: slow large uploads at once get 503, never exhaust memory
start_daemon "$T/d7" --max-body 1048576 || exit 1
head -c 1000000 /dev/zero | tr '\0' ' ' >"$T/m1"
pids=""
for k in 1 2 3 4 5 6; do
    curl -s -o /dev/null -w '%{http_code}\n' --limit-rate 400k -H 'Content-Type: application/json' \
        --data-binary @"$T/m1" "$URL/render" >"$T/u$k" &
    pids="$pids $!"
done
wait $pids
check "body budget: 503 beyond four bodies in flight" 'cat "$T"/u* | grep -q 503 && ! cat "$T"/u* | grep -vqE "^(400|503)$"'
check "daemon up after the uploads" 'alive'
stop_daemon

# ---- TLS 1.2+ ---------------------------------------------------------------------------------
openssl req -x509 -newkey rsa:2048 -nodes -keyout "$T/key.pem" -out "$T/cert.pem" -days 1 -subj /CN=127.0.0.1 >/dev/null 2>&1
start_daemon "$T/d6" --tls-cert "$T/cert.pem" --tls-key "$T/key.pem" || exit 1
check "TLS handshake" '[ "$(curl -s --cacert "$T/cert.pem" -o /dev/null -w "%{http_code}" "$URL/livez")" = 200 ]'
check "TLS 1.1 refused" '! curl -sk --tlsv1.1 --tls-max 1.1 -o /dev/null "$URL/livez"'
tls12() { echo | timeout 5 openssl s_client -connect "127.0.0.1:$PORT" -tls1_2 -cipher "$1" 2>/dev/null | grep -q "Cipher is $1"; }
check "TLS 1.2: ECDHE with AEAD offered" 'tls12 ECDHE-RSA-AES128-GCM-SHA256 && tls12 ECDHE-RSA-CHACHA20-POLY1305'
check "TLS 1.2: static RSA and CBC-SHA1 refused" '! tls12 AES128-SHA && ! tls12 AES256-GCM-SHA384 && ! tls12 ECDHE-RSA-AES128-SHA'
check "TLS 1.3 offered" 'echo | timeout 5 openssl s_client -connect "127.0.0.1:$PORT" -tls1_3 2>/dev/null | grep -q "TLSv1.3"'
stop_daemon

finish
