#!/bin/sh
# A model's mesh computed once (issue 18): the default tolerance tied to the model and stated
# (X-Mesh-Tolerance-Mm), a repeat served from the cache with the same strong ETag (304 on
# If-None-Match) and no new job, the store's size unchanged by 100 repeats, the cache bounded by
# --mesh-cache and reported in /metrics, a model's meshes gone with the model and after an edit.
. "$(dirname "$0")/lib.inc"
C="${SURFD_DATA:-../shared/data}/contours"
[ -f "$C/dicompyler_heart.json" ] || { bad "../shared/data/contours not found"; finish; }
J='Content-Type: application/json'
field() { python3 -c "import json,sys; print(json.load(open(sys.argv[1])).get(sys.argv[2]))" "$T/body" "$1"; }
metric() { curl -s "$URL/metrics" | sed -n "s/^$1 //p"; }
start_daemon "$T/d" --mesh-cache 30000000 || exit 1
code=$(status POST /model -H "$J" --data-binary @"$C/dicompyler_heart.json"); id=$(field id); vol=$(field volume_mm3)
code=$(status GET "/models/$id/mesh"); cp "$T/body" "$T/a.stl"; etag=$(header ETag); tol=$(header X-Mesh-Tolerance-Mm)
check "the default mesh: the tolerance stated, a strong ETag, closed, within 0.05 % of the model's volume" '[ "$code" = 200 ] && [ -n "$tol" ] && echo "$etag" | grep -qE "^\"[0-9a-f]{32}\"$" && python3 tests/tools/stl_check.py "$T/a.stl" "$vol" | grep -qE "\((-|\+)0\.0[0-4]"'
check "... of a sensible size: under 8 MB for the heart (32 MB before)" '[ "$(wc -c <"$T/a.stl")" -lt 8000000 ]'
jobs=$(curl -s "$URL/jobs" | grep -o '"id"' | wc -l)
code=$(status GET "/models/$id/mesh")
check "a repeat: the same bytes and ETag, from the cache (no job)" '[ "$code" = 200 ] && [ "$(header ETag)" = "$etag" ] && cmp -s "$T/body" "$T/a.stl" && [ -z "$(header X-Job-Id)" ] && [ "$(metric "surfd_mesh_cache_lookups_total{result=\"hit\"}")" = 1 ]'
check "If-None-Match: 304" '[ "$(status GET "/models/$id/mesh" -H "If-None-Match: $etag")" = 304 ]'
# (the WAL left out: each repeat stamps the mesh used, a page the WAL keeps until its checkpoint at
# 1000 frames; a mesh is kept in values/ or the database)
size0=$(du -sk --exclude='*-wal' "$T/d" | cut -f1)
for _ in $(seq 100); do curl -s -o /dev/null "$URL/models/$id/mesh"; done
size1=$(du -sk --exclude='*-wal' "$T/d" | cut -f1)
check "100 repeats: no new job, the store's size unchanged (within 256 KB)" '[ "$(curl -s "$URL/jobs" | grep -o "\"id\"" | wc -l)" = "$jobs" ] && [ $((size1 - size0)) -lt 256 ]'
code=$(status GET "/models/$id/mesh?format=ply&tolerance=0.05")
check "another format and tolerance: its own entry (the tolerance as asked)" '[ "$code" = 200 ] && [ "$(header X-Mesh-Tolerance-Mm)" = 0.05 ] && [ "$(header ETag)" != "$etag" ]'
bytes=$(metric surfd_mesh_cache_bytes)
check "/metrics: surfd_mesh_cache_bytes counts both" '[ "$bytes" -gt "$(wc -c <"$T/a.stl")" ]'
for t in 0.03 0.02 0.015; do curl -s -o /dev/null "$URL/models/$id/mesh?tolerance=$t"; done
check "the cache stays within --mesh-cache (30 MB), the least used dropped" '[ "$(metric surfd_mesh_cache_bytes)" -le 30000000 ]'
check "a bad tolerance is a 422 at ?tolerance, cache or not" '[ "$(status GET "/models/$id/mesh?tolerance=-1")" = 422 ] && grep -q "?tolerance" "$T/body"'
code=$(status DELETE "/models/$id")
check "deleting the model drops its meshes" '[ "$code" = 204 ] && [ "$(metric surfd_mesh_cache_bytes)" = 0 ] && [ "$(status GET "/models/$id/mesh")" = 404 ]'
printf '{"bounds": [[-1.2, -1.2, -1.2], [1.2, 1.2, 1.2]], "cell": 0.1, "frep": {"sphere": {"center": [0, 0, 0], "radius": 1}}}' >"$T/s.json"
code=$(status POST /isosurface -H "$J" --data-binary @"$T/s.json"); iso=$(field id)
code=$(status GET "/models/$iso/mesh"); e1=$(header ETag)
code=$(status POST "/models/$iso/edit" -H "$J" --data-binary '{"op": "subtract", "object": {"box": {"min": [0, 0, 0], "max": [2, 2, 2]}}}')
code=$(status GET "/models/$iso/mesh")
check "an edit drops the model's meshes: the mesh after it is the edited one" '[ "$code" = 200 ] && [ -n "$e1" ] && [ "$(header ETag)" != "$e1" ] && [ -n "$(header X-Job-Id)" ]'
stop_daemon
start_daemon "$T/d2" --mesh-cache 0 || exit 1
code=$(status POST /model -H "$J" --data-binary @"$C/synthetic_ellipsoid.json"); id=$(field id)
status GET "/models/$id/mesh" >/dev/null; status GET "/models/$id/mesh" >/dev/null
check "--mesh-cache 0: every mesh a job, nothing kept" '[ -n "$(header X-Job-Id)" ] && [ "$(metric surfd_mesh_cache_bytes)" = 0 ]'
finish
