#!/bin/sh
# Build a model from slice contours, print its figures, and fetch its closed mesh.
# usage: model_mesh.sh CONTOURS.json|RTSTRUCT.dcm OUT.stl|OUT.ply|OUT.obj [ROI]
#        (SURFD_URL, SURFD_TOKEN from the environment)
set -eu
: "${SURFD_URL:=http://127.0.0.1:8080}"
auth=${SURFD_TOKEN:+Authorization: Bearer $SURFD_TOKEN}
case "$1" in *.dcm) type=application/dicom ;; *) type=application/json ;; esac
hdr=$(mktemp); trap 'rm -f "$hdr"' EXIT
curl -sSf ${auth:+-H "$auth"} -H "Content-Type: $type" --data-binary @"$1" -D "$hdr" \
     "$SURFD_URL/model?caps=dome${3:+&roi=$3}"
echo
model=$(sed -n 's/^[Ll]ocation: *\([^[:space:]]*\).*/\1/p' "$hdr")
curl -sSf ${auth:+-H "$auth"} "$SURFD_URL$model/mesh?format=${2##*.}" -o "$2"
