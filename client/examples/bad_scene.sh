#!/bin/sh
# What a mistake looks like: 422 with a problem+json body that points at the field.
# usage: bad_scene.sh
set -u
: "${SURFD_URL:=http://127.0.0.1:8080}"
curl -sS ${SURFD_TOKEN:+-H "Authorization: Bearer $SURFD_TOKEN"} -H 'Content-Type: application/json' \
     --data-binary '{"objects":[{"type":"bspline","degree":[1,1],"size":[2,2],"knots_u":[0,1,0,1],"knots_v":[0,0,1,1],"points":[[0,0,0],[1,0,0],[0,1,0],[1,1,1]]}]}' \
     -w '\n%{http_code}\n' "$SURFD_URL/render"
