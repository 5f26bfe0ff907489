#!/bin/sh
# Queue a render, poll its job, then fetch the result: for scripts that must not hold a connection.
# usage: render_async.sh SCENE OUT.png
set -eu
: "${SURFD_URL:=http://127.0.0.1:8080}"
auth=${SURFD_TOKEN:+"Authorization: Bearer $SURFD_TOKEN"}
location=$(curl -sSf ${auth:+-H "$auth"} -H 'Prefer: respond-async' -H 'Content-Type: text/plain' \
                --data-binary @"$1" -o /dev/null -w '%header{location}' "$SURFD_URL/render")
until curl -sSf ${auth:+-H "$auth"} "$SURFD_URL$location" | grep -qE '"state":"(succeeded|failed|cancelled)"'; do
    sleep 0.2
done
curl -sSf ${auth:+-H "$auth"} "$SURFD_URL$location/result" -o "$2"
