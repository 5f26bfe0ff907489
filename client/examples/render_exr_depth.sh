#!/bin/sh
# Newell's .bpt as it is, out as EXR with depth (Z) and normals, uv and ids.
# usage: render_exr_depth.sh teapot.bpt OUT.exr
set -eu
: "${SURFD_URL:=http://127.0.0.1:8080}"
curl -sSf ${SURFD_TOKEN:+-H "Authorization: Bearer $SURFD_TOKEN"} -H 'Content-Type: model/x-bpt' \
     --data-binary @"$1" "$SURFD_URL/render?output=exr&width=320&height=240" -o "$2"
