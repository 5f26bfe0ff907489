#!/bin/sh
# Render a scene and wait for the PNG (the connection is held until the job ends, up to sync-wait).
# usage: render_sync.sh SCENE.json OUT.png     (SURFD_URL, SURFD_TOKEN from the environment)
set -eu
: "${SURFD_URL:=http://127.0.0.1:8080}"
curl -sSf ${SURFD_TOKEN:+-H "Authorization: Bearer $SURFD_TOKEN"} \
     -H 'Content-Type: application/json' --data-binary @"$1" \
     "$SURFD_URL/render?width=640&height=480" -o "$2"
