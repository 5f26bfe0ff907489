#!/bin/sh
# No circles between the files of core/, api/ and daemon/ (issue 43; make check runs it):
#   1. calls: X.c -> Y.c when X.o uses a symbol Y.o defines, over the objects of a build (BUILD,
#      default build/san): what the linker sees, whichever header declared it. This is the graph of
#      the issue's circles (metrics read the service that calls it; the kinds' table, the kinds and
#      the service that starts them).
#   2. includes: file to file (X.c -> Y.h, X.h -> Y.h): headers that need each other.
# A header that gives a file's types to another part (store_backend.h: the backends' table over
# store.h's records) is no circle: types do not call.
# tsort(1) finds the loops: each is printed; the last line is "N passed, N failed" (tests/run.sh),
# the exit status 1 if there is a loop.
cd "$(dirname "$0")/../.." || exit 2
BUILD=${1:-build/san}
tmp=${TMPDIR:-/tmp}/circles.$$
trap 'rm -f "$tmp".*' EXIT
for f in $(find core api daemon -name '*.[ch]' -o -name '*.cpp'); do
    sed -n 's/^#include "\([^"]*\)".*/\1/p' "$f" | while read -r inc; do
        echo "$f $(realpath -m --relative-to=. "$(dirname "$f")/$inc")"
    done
done >"$tmp.inc"
objs=$(find "$BUILD/core" "$BUILD/api" "$BUILD/daemon" -name '*.o' 2>/dev/null)
if [ -z "$objs" ]; then
    echo "circles: no objects under $BUILD (build it first)" >&2
    exit 2
fi
for o in $objs; do
    m=${o#"$BUILD"/}
    nm --defined-only "$o" | awk -v m="${m%.o}" '$2 ~ /^[TDRBC]$/ {print $3, m}'
done | sort -u >"$tmp.defs"
for o in $objs; do
    m=${o#"$BUILD"/}
    nm -u "$o" | awk -v m="${m%.o}" '{print $2, m}'
done | sort -u >"$tmp.uses"
join "$tmp.uses" "$tmp.defs" | awk '$2 != $3 {print $2, $3}' | sort -u >"$tmp.sym"
bad=0 ok=0
for g in sym inc; do
    if ! tsort "$tmp.$g" >/dev/null 2>"$tmp.err"; then
        what=$([ $g = inc ] && echo "includes" || echo "calls ($BUILD)")
        echo "circles in the $what:"
        grep -v 'input contains a loop' "$tmp.err" | sed 's/^tsort: /  /'
        bad=$((bad + 1))
    else
        ok=$((ok + 1))
    fi
done
echo "$ok passed, $bad failed"
[ $bad -eq 0 ]
