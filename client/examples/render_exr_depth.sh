#!/bin/sh
# Renders Newell's .bpt as it is to an OpenEXR for compositing: float R, G, B, A, the depth Z
# (distance along the ray) and the AOVs asked for: normals (N.x N.y N.z), surface parameters (u v)
# and object ids (id).
# usage: render_exr_depth.sh teapot.bpt OUT.exr      (SURFD_URL, SURFD_TOKEN from the environment)
set -eu
: "${SURFD_URL:=http://127.0.0.1:8080}"
curl -sSf ${SURFD_TOKEN:+-H "Authorization: Bearer $SURFD_TOKEN"} -H 'Content-Type: model/x-bpt' \
     --data-binary @"$1" "$SURFD_URL/render?output=exr&aovs=normal,uv,id&width=320&height=240" -o "$2"
