#!/bin/sh
# The README works when pasted (issue 19): every command of its indented blocks that starts with
# curl, build/, client/examples/, python3 or id= is run as written (continuation lines and quoted
# newlines joined), from a copy of the project root's layout (build/ and client/ linked, ../shared
# beside it) against the real daemon in place of 127.0.0.1:8080; each must exit 0.
. "$(dirname "$0")/lib.inc"
[ -d "${SURFD_DATA:-../shared/data}" ] || { bad "../shared/data not found"; finish; }
start_daemon "$T/d" --sync-wait 30 || exit 1
W=$T/tree/root
mkdir -p "$W"
ln -s "$(pwd)/build" "$W/build"; ln -s "$(pwd)/client" "$W/client"
ln -s "$(cd "${SURFD_DATA:-../shared/data}/.." && pwd)" "$T/tree/shared"
python3 - README.md "$URL" >"$T/cmds.sh" <<'PY'
import re, sys
url = sys.argv[2]
cmds, cur = [], None
for line in open(sys.argv[1]).read().split("\n"):
    if cur is not None:  # inside a command: a backslash continuation or an open quote
        cur += "\n" + (line[4:] if line.startswith("    ") else line)
    elif line.startswith("    ") and re.match(r"(curl|build/|client/examples/|python3|id=)", line[4:]):
        cur = line[4:]
    else:
        continue
    text = re.sub(r"\s+#[^'\"]*$", "", cur)  # a trailing comment
    if text.endswith("\\") or text.count("'") % 2:
        continue
    cmds.append(text.replace("http://127.0.0.1:8080", url))
    cur = None
for k, c in enumerate(cmds):
    print(c)
    print('r=$?; echo; echo "rc $r %d"' % k)
PY
n=$(grep -c '^r=\$?; echo; echo "rc' "$T/cmds.sh")
check "the README has commands to run (at least 12)" '[ "$n" -ge 12 ]'
(cd "$W" && SURFD_URL="$URL" sh "$T/cmds.sh" >"$T/run.out" 2>"$T/run.err")
failed=$(grep '^rc [1-9]' "$T/run.out" | cut -d' ' -f3)
for k in $failed; do
    bad "README command $k exits non-zero: $(awk -v k="$k" 'BEGIN{n=0} /^r=\$\?; echo; echo "rc/{n++; next} n==k' "$T/cmds.sh" | head -3)"
done
check "every README command exits 0 ($n of them)" '[ "$(grep -c "^rc 0 " "$T/run.out")" = "$n" ]'
[ -n "$failed" ] && tail -20 "$T/run.err"
check "... and they made what they say (teapot.png, ducks.exr, ellipsoid.stl, heart.stl, rtss_Heart.stl)" '[ -s "$W/teapot.png" ] && [ -s "$W/ducks.exr" ] && [ -s "$W/ellipsoid.stl" ] && [ -s "$W/heart.stl" ] && [ -s "$W/rtss_Heart.stl" ]'
finish
