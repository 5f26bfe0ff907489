#!/bin/sh
# Runs every test given (unit test binaries and shell suites: make check's and make test's lists),
# TEST_JOBS at a time (the cores; each test has its own temporary directory, data dir and port),
# prints each one's "NAME N passed, N failed (Ns)" as it ends (after the last 40 lines of its output
# when something failed), and ends with the total in the same form. Exit status: 0 only if nothing
# failed. (`tests/run.sh --one TEST DIR` runs one, for the lanes.)
set -u
export SURFD_DATA="${SURFD_DATA:-$(cd "$(dirname "$0")/../../shared/data" 2>/dev/null && pwd)}"
if [ "${1:-}" = --one ]; then
    t=$2; sums=$3
    start=$(date +%s)
    out=$("$t" 2>&1); rc=$?
    line=$(printf '%s\n' "$out" | grep -E '^[0-9]+ passed, [0-9]+ failed$' | tail -n 1)
    p=$(echo "$line" | sed -n 's/^\([0-9]*\) passed.*/\1/p'); f=$(echo "$line" | sed -n 's/.* \([0-9]*\) failed$/\1/p')
    [ -z "$p" ] && { p=0; f=1; }
    [ "$rc" -ne 0 ] && [ "$f" -eq 0 ] && f=1
    echo "$p $f" >"$sums/$(echo "$t" | tr / _)"
    block=$(printf '%-28s %3s passed, %s failed (%ss)' "$(basename "$t")" "$p" "$f" "$(($(date +%s) - start))")
    [ "$f" -ne 0 ] && block=$(printf '%s\n%s' "$(printf '%s\n' "$out" | tail -n 40)" "$block")
    printf '%s\n' "$block" # one write: the lanes' lines do not mix
    exit 0
fi
sums=$(mktemp -d)
trap 'rm -rf "$sums"' EXIT
for t in "$@"; do [ -e "$t" ] && printf '%s\n' "$t"; done |
    xargs -P "${TEST_JOBS:-$(nproc 2>/dev/null || echo 2)}" -I '{}' "$0" --one '{}' "$sums"
pass=0; fail=0; ran=0
for s in "$sums"/*; do
    [ -e "$s" ] || continue
    read -r p f <"$s"
    pass=$((pass + p)); fail=$((fail + f)); ran=$((ran + 1))
done
n=0; for t in "$@"; do [ -e "$t" ] && n=$((n + 1)); done
[ "$ran" -eq "$n" ] || { echo "$((n - ran)) of $n tests left no result"; fail=$((fail + n - ran)); }
echo "$pass passed, $fail failed"
[ "$fail" -eq 0 ]
