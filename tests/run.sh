#!/bin/sh
# Runs every test binary given (and the CLI, API and web page shell tests), adds up their "N passed, N failed" lines,
# and ends with the total in the same form. Exit status: 0 only if nothing failed.
set -u
pass=0; fail=0
export SURFD_DATA="${SURFD_DATA:-$(cd "$(dirname "$0")/../../shared/data" 2>/dev/null && pwd)}"
for t in "$@" tests/cli/*.sh tests/api/*.sh tests/web/*.sh tests/deploy/*.sh tests/fuzz/*.sh; do
    [ -e "$t" ] || continue
    name=$(basename "$t")
    start=$(date +%s)
    out=$("$t" 2>&1); rc=$?
    line=$(printf '%s\n' "$out" | grep -E '^[0-9]+ passed, [0-9]+ failed$' | tail -n 1)
    p=$(echo "$line" | sed -n 's/^\([0-9]*\) passed.*/\1/p'); f=$(echo "$line" | sed -n 's/.* \([0-9]*\) failed$/\1/p')
    [ -z "$p" ] && { p=0; f=1; }
    [ "$rc" -ne 0 ] && [ "$f" -eq 0 ] && f=1
    if [ "$f" -ne 0 ]; then printf '%s\n' "$out" | tail -n 40; fi
    printf '%-28s %3s passed, %s failed (%ss)\n' "$name" "$p" "$f" "$(( $(date +%s) - start ))"
    pass=$((pass + p)); fail=$((fail + f))
done
echo "$pass passed, $fail failed"
[ "$fail" -eq 0 ]
