#!/bin/sh
# Several nodes on one PostgreSQL (issue 13): a real server (initdb into the test's directory, a
# Unix socket only) and three daemons on loopback ports. Jobs posted to any node run once; every
# node answers for every job; a synchronous request is answered when another node ran its job;
# a node killed or stopped mid-render loses its job to another, which finishes it (attempts 2),
# and the stopped one cannot finish it after; cancel works across nodes; a database restart loses
# nothing. Every wait is bounded.
. "$(dirname "$0")/lib.inc"
. tests/tools/pg.inc

J='Content-Type: application/json'
C="${SURFD_DATA:-../shared/data}/contours"
[ -f "$C/synthetic_ellipsoid.json" ] || { bad "../shared/data/contours not found"; checks_done; exit 1; }
LEASE=3
chmod 755 "$T" # the cluster's owner (nobody, under root) reaches its directory inside
pg_start "$T/pg" || { bad "PostgreSQL would not start"; checks_done; exit 1; }
trap 'for n in n1 n2 n3; do node_kill $n; done; pg_stop; rm -rf "$T"' EXIT

# start_node NAME [ARGS...]: a daemon on the shared store; sets URL_NAME and PID_NAME
start_node() {
    n=$1; shift
    : >"$T/$n.log"
    $S serve --listen 127.0.0.1:0 --data-dir "$T/$n" --store "$PG_URI" --node-name "$n" --lease $LEASE \
        --log-level info "$@" >>"$T/$n.log" 2>&1 &
    eval "PID_$n=$!"
    for _ in $(seq 200); do
        port=$(sed -n 's/.*listening on http:\/\/127.0.0.1:\([0-9]*\).*/\1/p' "$T/$n.log" | tail -n 1)
        [ -n "$port" ] && curl -s -o /dev/null "http://127.0.0.1:$port/livez" && { eval "URL_$n=http://127.0.0.1:$port"; return 0; }
        sleep 0.05
    done
    echo "node $n did not start:"; cat "$T/$n.log"
    return 1
}
node_kill() { eval "p=\${PID_$1:-}"; [ -n "$p" ] && kill -9 "$p" 2>/dev/null; eval "PID_$1="; }
node_url() { eval "echo \$URL_$1"; }
# on NODE METHOD PATH [curl args]: status code; body in $T/body
on() {
    u=$(node_url "$1"); m=$2; p=$3; shift 3
    curl -s -m 120 -X "$m" -o "$T/body" -D "$T/hdr" -w '%{http_code}' "$@" "$u$p"
}
field() { python3 -c "import json,sys; print(json.load(open(sys.argv[1])).get(sys.argv[2]))" "$T/body" "$1"; }
# job_field NODE ID FIELD
job_field() { on "$1" GET "/jobs/$2" >/dev/null; field "$3"; }
# until_job NODE ID FIELD VALUE SECONDS
until_job() {
    for _ in $(seq $(($5 * 10))); do
        [ "$(job_field "$1" "$2" "$3")" = "$4" ] && return 0
        sleep 0.1
    done
    return 1
}
# long_render NODE [SIZE]: a render of about 15 s on one sanitized worker (SIZE 240: 5 s, for a job
# that is taken over and run again whole), in bands a cancel stops between
long_render() {
    on "$1" POST "/render?width=${2:-400}&height=${2:-400}&method=montecarlo" -H 'Prefer: respond-async' -H "$J" \
        --data-binary @"${SURFD_DATA:-../shared/data}/scenes/teacup.json" >/dev/null
    field id
}

for n in n1 n2 n3; do start_node $n --threads 2 || { bad "node $n did not start"; checks_done; exit 1; }; done

section() { echo "$(date +%T) $*"; }
section "exactly once"
# ---- jobs posted to any node run exactly once ----------------------------------------------------
: >"$T/ids"
for k in $(seq 30); do
    n=n$((k % 3 + 1))
    on $n POST /volume -H 'Prefer: respond-async' -H "$J" --data-binary @"$C/synthetic_ellipsoid.json" >/dev/null
    field id >>"$T/ids"
done
done_all() { [ "$(pg_sql "SELECT count(*) FROM jobs WHERE state='succeeded' AND kind='volume'")" = 30 ]; }
for _ in $(seq 600); do done_all && break; sleep 0.1; done
check "30 jobs posted round the three nodes all succeed" 'done_all'
check "... each ran once (one attempt, one claim)" '[ "$(pg_sql "SELECT count(*) FROM jobs WHERE kind='"'volume'"' AND attempts=1 AND fence=1")" = 30 ]'
check "... and more than one node ran them" '[ "$(pg_sql "SELECT count(DISTINCT node) FROM jobs WHERE kind='"'volume'"'")" -ge 2 ]'
id=$(head -n 1 "$T/ids")
same=1
on n1 GET "/jobs/$id/result" >/dev/null; cp "$T/body" "$T/r1"
for n in n2 n3; do
    [ "$(on $n GET "/jobs/$id/result")" = 200 ] && cmp -s "$T/body" "$T/r1" || same=0
    [ "$(on $n GET "/jobs/$id")" = 200 ] && [ "$(field state)" = succeeded ] || same=0
done
check "a job's resource and result are the same from every node" '[ $same = 1 ] && grep -q volume_mm3 "$T/r1"'
check "every node lists every job" '[ "$(on n3 GET /jobs)" = 200 ] && [ "$(grep -o "\"kind\":\"volume\"" "$T/body" | wc -l)" = 30 ]'

section sync
CT="${SURFD_DATA:-../shared/data}/volumes/ct_head_crop64_int16.raw"
code=$(on n2 POST "/isosurface?iso=226.5&dims=64,64,64&type=int16&spacing=0.9570312,0.9570312,1.5" \
    -H 'Content-Type: application/octet-stream' --data-binary @"$CT")
mid=$(field id)
check "an isosurface (its volume streamed into the database in chunks): 201 on any node" '[ "$code" = 201 ] && [ "$(field boundary_edges)" = 0 ]'
check "... its mesh downloads closed from another node" '[ "$(on n3 GET "/models/$mid/mesh?format=stl")" = 200 ] && python3 tests/tools/stl_check.py "$T/body" 57529.6 >/dev/null'
etag3=$(header ETag) # the mesh just made on n3
on n1 GET "/models/$mid/mesh?format=stl" >/dev/null
check "... once made, every node serves it from the shared cache: the same ETag, no job" '[ -n "$etag3" ] && [ "$(header ETag)" = "$etag3" ] && [ -z "$(header X-Job-Id)" ]'
check "... and no node keeps a fetched copy of the volume" '! find "$T"/n?/scratch -type f 2>/dev/null | grep -q .'
# edits posted round the nodes: each node brings its hierarchy up to the store's edits first
Q="iso=226.5&dims=64,64,64&type=int16&spacing=0.9570312,0.9570312,1.5&levels=2&max_error=0.5"
E=tests/tools/edit_tool.py
code=$(on n1 POST "/isosurface?$Q" -H 'Content-Type: application/octet-stream' --data-binary @"$CT"); eid=$(field id)
cp "$CT" "$T/v.raw"; edits_ok=1; k=0
for r in 20,24,17 0,50,52 30,5,40 21,25,18; do
    k=$((k + 1))
    python3 $E block 10 $((k % 2 ? 1400 : -1000)) $((k % 2 ? -100 : 300)) 3.5 "$T/b.raw"
    python3 $E apply "$T/v.raw" 64,64,64 "$r,10,10,10" "$T/b.raw" "$T/v2.raw" && mv "$T/v2.raw" "$T/v.raw"
    code=$(on n$((k % 3 + 1)) POST "/models/$eid/edit?region=$r,10,10,10" -H 'Content-Type: application/octet-stream' --data-binary @"$T/b.raw")
    [ "$code" = 200 ] && [ "$(field edits)" = $k ] || edits_ok=0
done
check "four edits posted round the nodes: 200 each, counted in order" '[ $edits_ok = 1 ]'
on n2 GET "/models/$eid/mesh?format=stl" >/dev/null; cp "$T/body" "$T/edited.stl"
code=$(on n3 POST "/isosurface?$Q" -H 'Content-Type: application/octet-stream' --data-binary @"$T/v.raw"); fid=$(field id)
on n1 GET "/models/$fid/mesh?format=stl" >/dev/null
check "... the mesh equals a fresh extraction of the edited volume, triangle for triangle" '[ "$code" = 201 ] && python3 $E same "$T/edited.stl" "$T/body"'
check "... the volume and its four edits kept in the database (beside them, seq < 0, the mesh's changes)" '[ "$(pg_sql "SELECT count(*) FROM model_volumes WHERE model='"'$eid'"' AND seq >= 0")" = 5 ]'

# ---- a synchronous request answered when another node runs its job ----------------------------------
node_kill n1; node_kill n2; node_kill n3
start_node n1 --threads 1; start_node n2 --threads 1
busy=$(long_render n1) # n1's worker is busy with it (or n2's: then n1 stays idle...)
until_job n1 "$busy" state running 20
holder=$(job_field n1 "$busy" node)
other=$([ "$holder" = n1 ] && echo n2 || echo n1)
# the holder is full, the other idle: a synchronous volume posted to the holder runs on the other
code=$(on "$holder" POST /volume -H "$J" --data-binary @"$C/synthetic_bean.json")
sid=$(tr -d '\r' <"$T/hdr" | sed -n 's/^X-Job-Id: //p')
check "a synchronous POST on the busy node answers 200 with the result" '[ "$code" = 200 ] && grep -q volume_mm3 "$T/body"'
check "... which the other node computed" '[ "$(job_field "$holder" "$sid" node)" = "$other" ]'

section cancel
# ---- cancel across nodes ----------------------------------------------------------------------------
code=$(on "$other" POST "/jobs/$busy/cancel")
check "cancel of a render running on another node: 202" '[ "$code" = 202 ]'
check "... and it stops there within seconds" 'until_job "$other" "$busy" state cancelled 20'

section kill
# ---- kill -9 of a node mid-render: its job finishes once, elsewhere ------------------------------------
start_node n3 --threads 1
id=$(long_render n2 240)
until_job n2 "$id" state running 20
victim=$(job_field n2 "$id" node)
node_kill "$victim"
survivor=$(for n in n1 n2 n3; do [ "$n" != "$victim" ] && echo $n; done | head -n 1)
t0=$(date +%s)
check "kill -9 of the node rendering: another takes the job over after the lease" 'until_job "$survivor" "$id" state succeeded 120'
check "... it ran twice in all (attempts 2), the second elsewhere" '[ "$(job_field "$survivor" "$id" attempts)" = 2 ] && [ "$(job_field "$survivor" "$id" node)" != "$victim" ]'
check "... the result is there, from any node" '[ "$(on "$survivor" GET "/jobs/$id/result")" = 200 ] && [ "$(header Content-Type)" = image/png ]'
echo "takeover after kill -9: $(( $(date +%s) - t0 )) s (lease ${LEASE} s)"
start_node "$victim" --threads 1

section stop
# ---- a node stopped past its lease cannot finish the job it lost ------------------------------------------
id=$(long_render n1 240)
until_job n1 "$id" state running 20
frozen=$(job_field n1 "$id" node)
eval "kill -STOP \$PID_$frozen"
check "a node stopped (SIGSTOP) past its lease: its job is run by another" 'until_job "$(for n in n1 n2 n3; do [ "$n" != "$frozen" ] && echo $n; done | head -n 1)" "$id" attempts 2 30'
eval "kill -CONT \$PID_$frozen"
live=$(for n in n1 n2 n3; do [ "$n" != "$frozen" ] && echo $n; done | head -n 1)
check "... and finishes there" 'until_job "$live" "$id" state succeeded 120'
check "... the stopped node, woken, did not finish it (its claim was lost)" '[ "$(job_field "$live" "$id" node)" != "$frozen" ] && [ "$(pg_sql "SELECT fence FROM jobs WHERE id='"'$id'"'")" = 2 ]'
for _ in $(seq 100); do grep -q "claim was lost\|outcome is dropped" "$T/$frozen.log" && break; sleep 0.1; done
check "... and said so in its log" 'grep -q "claim was lost\|outcome is dropped" "$T/$frozen.log"'

section restart
# ---- a PostgreSQL restart loses nothing --------------------------------------------------------------------
: >"$T/ids2"
for k in $(seq 6); do
    on n$((k % 3 + 1)) POST /volume -H 'Prefer: respond-async' -H "$J" --data-binary @"$C/synthetic_bean.json" >/dev/null
    field id >>"$T/ids2"
done
pg_stop
check "/readyz: 503 while the database is away" '[ "$(on n1 GET /readyz)" = 503 ]'
pg_ctl_start
ready=0
# (every node: each finds the database back on its own, and n3 is asked next)
for _ in $(seq 100); do
    [ "$(on n1 GET /readyz)$(on n2 GET /readyz)$(on n3 GET /readyz)" = 200200200 ] && ready=1 && break
    sleep 0.1
done
check "... 200 when it is back" '[ $ready = 1 ]'
code=$(on n3 POST /volume -H "$J" --data-binary @"$C/synthetic_ellipsoid.json")
check "a node takes new jobs after the restart" '[ "$code" = 200 ]'
all=1
while read -r id; do until_job n1 "$id" state succeeded 60 || all=0; done <"$T/ids2"
check "jobs accepted before the restart all succeed" '[ $all = 1 ]'

for n in n1 n2 n3; do node_kill $n; done
if grep -qE "ERROR: (Address|Thread)Sanitizer|runtime error:" "$T"/n?.log; then
    bad "a sanitizer spoke in a node's log:"; grep -h -A20 -E "Sanitizer|runtime error:" "$T"/n?.log | head -40
fi
checks_done
