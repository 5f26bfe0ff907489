#!/bin/sh
# Repeat views of a stored model (issue 17): GET /models/{id}/render keeps the model's parsed
# objects and hierarchy in memory (frame-cache) and prepares only the camera's part for the next
# view - the image byte for byte the one a fresh preparation makes (POST /render of the same scene,
# which is prepared whole), for a contour model, an isosurface, the mesh method and after an edit;
# the cache's hits in /metrics; --frame-cache 0 keeps nothing.
. "$(dirname "$0")/lib.inc"
C="${SURFD_DATA:-../shared/data}/contours"
[ -f "$C/synthetic_ellipsoid.json" ] || { bad "../shared/data/contours not found"; finish; }
J='Content-Type: application/json'
field() { python3 -c "import json,sys; print(json.load(open(sys.argv[1])).get(sys.argv[2]))" "$T/body" "$1"; }
metric() { curl -s "$URL/metrics" | sed -n "s/^$1 //p"; }
start_daemon "$T/d" || exit 1
same_view() { # same_view ID QUERY: the cached view and a fresh one are the same bytes
    status GET "/models/$1/render?$2" >/dev/null; cp "$T/body" "$T/cached"
    status POST "/render?$2" -H "$J" --data-binary "{ \"objects\": [ {\"type\": \"model\", \"id\": \"$1\"} ] }" >/dev/null
    [ -s "$T/cached" ] && { cmp -s "$T/body" "$T/cached" || python3 -c "
import sys; sys.path.insert(0, 'tests/tools'); import exr_read
a, b = exr_read.read(sys.argv[1]), exr_read.read(sys.argv[2])
sys.exit(0 if a[:2] == b[:2] and all(str(a[2][k]) == str(b[2][k]) for k in a[2]) and a[2].keys() == b[2].keys() else 1)" "$T/body" "$T/cached" 2>/dev/null; } # EXR: the pixels (its header has the second it was written)
}
code=$(status POST /model -H "$J" --data-binary @"$C/synthetic_ellipsoid.json"); id=$(field id)
status GET "/models/$id/render?width=96&height=72" >/dev/null
check "a contour model's first view builds its hierarchy (a miss), kept: its bytes in surfd_frame_cache_bytes" '[ "$(metric "surfd_frame_cache_lookups_total{result=\"miss\"}")" = 1 ] && [ "$(metric surfd_frame_cache_bytes)" -gt 100000 ]'
check "... a second view from another side uses it (a hit), the image byte for byte a fresh preparation's" 'same_view "$id" "width=96&height=72&azimuth=120&elevation=10" && [ "$(metric "surfd_frame_cache_lookups_total{result=\"hit\"}")" = 1 ]'
check "... orthographic, an axis view: the same as fresh" 'same_view "$id" "width=64&height=48&projection=orthographic&view=%2Bz"'
check "... EXR with AOVs: the same as fresh" 'same_view "$id" "width=64&height=48&output=exr&aovs=normal,uv,id"'
check "... the mesh method: its own hierarchy, the same as fresh" 'same_view "$id" "width=64&height=48&method=mesh"'
# a cached model's view checks its query against the cached objects: the answers a fresh parse gives
bad_view() { # bad_view ID QUERY POINTER: 422 at POINTER when asked (async: no job made), as POST /render of the same scene answers
    code=$(status GET "/models/$1/render?$2" -H 'Prefer: respond-async'); cp "$T/body" "$T/viewed"
    [ "$code" = 422 ] && is_problem 422 && grep -q "\"pointer\":\"$3\"" "$T/viewed" &&
        [ "$(status POST "/render?$2" -H "$J" --data-binary "{\"objects\": [{\"type\": \"model\", \"id\": \"$1\"}]}")" = 422 ] &&
        grep -q "\"pointer\":\"$3\"" "$T/body" && alive
}
check "... a bad option on a cached view: 422 at its field, as a fresh parse says, the daemon up" 'bad_view "$id" "width=0&height=48" "?width" && bad_view "$id" "width=64&height=48&elevation=95" "?elevation" && bad_view "$id" "width=64&samples=999" "?samples" && bad_view "$id" "width=64&eye=1,1,1&target=1,1,1" /camera/target'
check "... and a view of a model nobody stored: 404 as before" '[ "$(status GET "/models/00000000000000000000000000000000/render?width=8")" = 404 ]'
printf '{"bounds": [[-1.2, -1.2, -1.2], [1.2, 1.2, 1.2]], "cell": 0.1, "frep": {"sphere": {"center": [0, 0, 0], "radius": 1}}}' >"$T/s.json"
code=$(status POST /isosurface -H "$J" --data-binary @"$T/s.json"); iso=$(field id)
status GET "/models/$iso/render?width=64&height=48" >/dev/null
check "an isosurface model's second view: the same as fresh" 'same_view "$iso" "width=64&height=48&azimuth=200"'
check "... the map method on its cached mesh: 422 at ?method, as a fresh parse says" 'bad_view "$iso" "width=64&height=48&method=map" "?method"'
cp "$T/cached" "$T/before"
code=$(status POST "/models/$iso/edit" -H "$J" --data-binary '{"op": "subtract", "object": {"box": {"min": [0, 0, 0], "max": [2, 2, 2]}}}')
check "... after an edit, the edited model (a new hierarchy), the same as fresh" '[ "$code" = 200 ] && same_view "$iso" "width=64&height=48&azimuth=200" && ! cmp -s "$T/body" "$T/before" '
stop_daemon
start_daemon "$T/d" --frame-cache 1000 || exit 1
status GET "/models/$id/render?width=64&height=48" >/dev/null
check "a hierarchy over --frame-cache (1000 bytes) is used for its view and not kept: the next view builds it again" 'same_view "$id" "width=64&height=48&azimuth=10" && [ "$(metric "surfd_frame_cache_lookups_total{result=\"miss\"}")" = 2 ] && [ "$(metric "surfd_frame_cache_lookups_total{result=\"hit\"}")" = 0 ]'
stop_daemon
# the budget counts a hierarchy's leaves, seams and Embree's nodes (the heart's about 40 MB, its
# process growing 59 MB), not only its patches (2.7 MB): under a 20 MB budget it is not kept
start_daemon "$T/d" --frame-cache 20000000 || exit 1
code=$(status POST /model -H "$J" --data-binary @"$C/dicompyler_heart.json"); heart=$(field id)
status GET "/models/$heart/render?width=64&height=48" >/dev/null; status GET "/models/$heart/render?width=64&height=48" >/dev/null
check "the heart's hierarchy, over a 20 MB frame-cache, is not kept: two views, two misses, nothing held" '[ "$(metric "surfd_frame_cache_lookups_total{result=\"miss\"}")" = 2 ] && [ "$(metric surfd_frame_cache_bytes)" = 0 ]'
stop_daemon
start_daemon "$T/d" --frame-cache 0 || exit 1
status GET "/models/$id/render?width=64&height=48" >/dev/null; status GET "/models/$id/render?width=64&height=48" >/dev/null
check "--frame-cache 0: every view a miss, still rendered" '[ "$(header Content-Type)" = image/png ] && [ "$(metric "surfd_frame_cache_lookups_total{result=\"hit\"}")" = 0 ]'
finish
