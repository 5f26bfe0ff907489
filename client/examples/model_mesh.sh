#!/bin/sh
# Builds a model from slice contours (or every ROI of an RT Structure Set), prints its figures
# (the model resource: volume_mm3, the baselines, caps...), and fetches each model's closed mesh.
# usage: model_mesh.sh CONTOURS.json|RTSTRUCT.dcm OUT.stl|OUT.ply|OUT.obj|OUT.vtp|OUT.vtk
#                      [--caps flat|slab|dome] [--roi "ROI NAME"]
#   one model: its mesh in OUT; an RTSTRUCT without --roi: every ROI with contours, each mesh in
#   OUT's name with _ROI before the extension (spaces and slashes as _)
#   (SURFD_URL, SURFD_TOKEN from the environment)
set -eu
: "${SURFD_URL:=http://127.0.0.1:8080}"
in=$1 out=$2; shift 2
caps="" roi=""
while [ $# -gt 0 ]; do
    case $1 in
    --caps) caps=$2; shift 2 ;;
    --roi) roi=$2; shift 2 ;;
    *) echo "usage: model_mesh.sh CONTOURS OUT.EXT [--caps flat|slab|dome] [--roi NAME]" >&2; exit 2 ;;
    esac
done
urlencode() { # a query value, percent-encoded (ROI names have spaces)
    s=$1
    while [ -n "$s" ]; do
        c=${s%"${s#?}"}; s=${s#?}
        case $c in [A-Za-z0-9.~_-]) printf %s "$c" ;; *) printf '%%%02X' "'$c" ;; esac
    done
}
auth=${SURFD_TOKEN:+Authorization: Bearer $SURFD_TOKEN}
# call OUT CURL-ARGS...: the answer's body in OUT, whether it came at once (200, 201) or, when the
# job took longer than the server waits (202, a busy server or a large structure set), from its job
call() {
    dst=$1; shift
    got=$(curl -sS ${auth:+-H "$auth"} -o "$dst" -w '%{http_code} %header{location}' "$@")
    case $got in
    202*)
        job=${got#202 }
        until curl -sSf ${auth:+-H "$auth"} "$SURFD_URL$job" | grep -qE '"state":"(succeeded|failed|cancelled)"'; do
            sleep 0.2
        done
        curl -sSf ${auth:+-H "$auth"} "$SURFD_URL$job/result" -o "$dst" ;;
    2*) ;;
    *) cat "$dst" >&2; echo >&2; return 1 ;;
    esac
}
tmp=$(mktemp)
trap 'rm -f "$tmp"' EXIT
case "$in" in *.dcm) type=application/dicom ;; *) type=application/json ;; esac
query=${caps:+caps=$caps}${roi:+${caps:+&}roi=$(urlencode "$roi")}
call "$tmp" -H "Content-Type: $type" --data-binary @"$in" "$SURFD_URL/model${query:+?$query}"
answer=$(cat "$tmp")
echo "$answer"
ids=$(printf '%s' "$answer" | grep -o '"id":"[0-9a-f]\{32\}"' | cut -d'"' -f4)
n=$(echo "$ids" | wc -l)
for id in $ids; do
    file=$out
    if [ "$n" -gt 1 ]; then # one file per ROI: its name from the model resource
        name=$(curl -sSf ${auth:+-H "$auth"} "$SURFD_URL/models/$id" | sed 's/^{"name":"\([^"]*\)".*/\1/' | tr ' /' '__')
        file="${out%.*}_$name.${out##*.}"
    fi
    call "$file" "$SURFD_URL/models/$id/mesh?format=${out##*.}"
    echo "$file" >&2
done
