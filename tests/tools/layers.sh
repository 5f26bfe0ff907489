#!/bin/sh
# The include rules of the source tree (make layers; every build runs it):
#   core/ is layered, each folder including only itself and the folders below it:
#     base <- geom <- trace | contour | iso <- matrix   (trace, contour and iso do not see each other;
#     matrix sees iso and trace: a model's voxels by rays)
#   core/ includes nothing of api/, daemon/ or client/, and no library of HTTP, JSON, threads,
#   storage or logging; api/ includes core/ and api/, never daemon/ or client/; the tests of a
#   core/ layer (tests/core/LAYER) include that layer and those below it.
# Prints each broken rule as FILE: #include ... and exits 1 if there is one.
# `layers.sh --below LAYER` prints the folders LAYER may include (the Makefile links a layer's unit
# tests with them alone).
cd "$(dirname "$0")/../.." || exit 2
allowed() { # folder of core -> the folders it may include
    case $1 in
    base) echo "base" ;;
    geom) echo "base geom" ;;
    trace) echo "base geom trace" ;;
    contour) echo "base geom contour" ;;
    iso) echo "base geom iso" ;;
    matrix) echo "base geom iso trace matrix" ;;
    *) echo "" ;;
    esac
}
if [ "${1:-}" = --below ]; then
    allowed "$2"
    exit 0
fi
bad=0
say() { echo "$1: $2"; bad=1; }
for f in core/*.c core/*.h core/*.cpp; do
    [ -e "$f" ] && say "$f" "every core source belongs to a folder (base, geom, trace, contour, iso, matrix)"
done
for f in $(find core -name '*.[ch]' -o -name '*.cpp'); do
    dir=$(basename "$(dirname "$f")")
    ok=$(allowed "$dir")
    [ -z "$ok" ] && say "$f" "core/$dir is not one of the layers"
    grep -n '#include' "$f" | while IFS= read -r line; do
        inc=$(printf '%s' "$line" | sed -n 's/.*#include *\([<"][^>"]*[>"]\).*/\1/p')
        case $inc in
        '<jansson.h>'|'<microhttpd.h>'|'<pthread.h>'|'<sqlite3.h>'|'<libpq-fe.h>'|'<curl/'*|'<threads.h>'|'<syslog.h>')
            echo "$f: $line (core has no HTTP, JSON, threads, storage or logging)" ;;
        '"'*'/'*'"')
            target=$(realpath -m --relative-to=. "$(dirname "$f")/$(printf '%s' "$inc" | tr -d '"')")
            case $target in
            core/*/*) layer=$(echo "$target" | cut -d/ -f2)
                      case " $ok " in *" $layer "*) ;; *) echo "$f: $line (core/$dir may include: $ok)" ;; esac ;;
            *) echo "$f: $line (core includes only core)" ;;
            esac ;;
        esac
    done
done >"${TMPDIR:-/tmp}/layers.$$"
for f in $(find tests/core -name '*.[ch]'); do # a layer's tests include that layer and those below it
    dir=$(basename "$(dirname "$f")")
    ok=$(allowed "$dir")
    grep -n '#include "' "$f" | while IFS= read -r line; do
        inc=$(printf '%s' "$line" | sed -n 's/.*#include *"\([^"]*\)".*/\1/p')
        target=$(realpath -m --relative-to=. "$(dirname "$f")/$inc")
        case $target in
        core/*/*) layer=$(echo "$target" | cut -d/ -f2)
                  case " $ok " in *" $layer "*) ;; *) echo "$f: $line (a test of core/$dir may include: $ok)" ;; esac ;;
        api/* | daemon/* | client/*) echo "$f: $line (tests of core/ include only core; tests/api/ reads with api/)" ;;
        esac
    done
done >>"${TMPDIR:-/tmp}/layers.$$"
for f in api/*.c api/*.h api/*.cpp; do
    grep -Hn '#include "\.\./\(daemon\|client\)/' "$f"
done >>"${TMPDIR:-/tmp}/layers.$$"
if [ -s "${TMPDIR:-/tmp}/layers.$$" ]; then
    cat "${TMPDIR:-/tmp}/layers.$$"
    bad=1
fi
rm -f "${TMPDIR:-/tmp}/layers.$$"
exit $bad
