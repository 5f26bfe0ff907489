#!/bin/sh
# make check: every fuzz target (built with the sanitizers and the daemon's allocator wrappers over
# tests/fuzz/replay.c -DTORTURE) runs each of its own seeds once for every allocation it makes,
# with that allocation refused (curl's torture tests; up to 2000 runs an input): every run must end
# cleanly, without a sanitizer report, and give back every byte it took. A target without seeds of
# its own takes its first two shared ones.
set -u
cd "$(dirname "$0")/../.." || exit 1
. tests/check.inc
. tests/fuzz/seeds.inc
export ASAN_OPTIONS="${ASAN_OPTIONS:-detect_leaks=1:allocator_may_return_null=1:malloc_fill_byte=1}" UBSAN_OPTIONS="${UBSAN_OPTIONS:-print_stacktrace=1}"
for src in tests/fuzz/fuzz_*.c; do
    t=${src#tests/fuzz/fuzz_}; t=${t%.c}; bin=build/tests/fuzz/torture_$t
    [ -x "$bin" ] || { bad "torture $t: $bin is not built"; continue; }
    list="tests/fuzz/seeds/$t"
    [ -d "$list" ] || list=$(seeds "$t" | xargs -r ls -S | tail -n 1) # the smallest
    if [ -z "$list" ]; then
        needs_shared "$t" && [ ! -d "$DATA" ] && { bad "torture $t: no seeds (../shared/data missing?)"; continue; }
        continue
    fi
    # shellcheck disable=SC2086
    out=$("$bin" $list 2>&1); rc=$?
    runs=$(printf '%s\n' "$out" | sed -n 's/^[0-9]* inputs, \([0-9]*\) runs.*/\1/p')
    check "torture $t: ${runs:-?} runs, each with one allocation refused, all clean" '[ "$rc" = 0 ] && [ -n "$runs" ] && ! printf "%s" "$out" | grep -q "ERROR: [A-Za-z]*Sanitizer\|runtime error"'
    [ "$rc" = 0 ] || printf '%s\n' "$out" | tail -30
done
checks_done
