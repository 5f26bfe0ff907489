#!/bin/sh
# make check: every fuzz target (built with gcc and the sanitizers over tests/fuzz/replay.c) replays
# its seeds and the crashers kept in tests/fuzz/crashers/NAME: each once crashed or hung a decoder.
set -u
cd "$(dirname "$0")/../.." || exit 1
. tests/check.inc
. tests/fuzz/seeds.inc
export ASAN_OPTIONS="${ASAN_OPTIONS:-detect_leaks=1:max_allocation_size_mb=512:allocator_may_return_null=1:malloc_fill_byte=1}" UBSAN_OPTIONS="${UBSAN_OPTIONS:-print_stacktrace=1}"
for src in tests/fuzz/fuzz_*.c; do
    t=${src#tests/fuzz/fuzz_}; t=${t%.c}; bin=build/tests/fuzz/replay_$t
    [ -x "$bin" ] || { bad "replay $t: $bin is not built"; continue; }
    list=$(seeds "$t")
    if [ -z "$list" ] || { needs_shared "$t" && [ ! -d "$DATA" ]; }; then
        bad "replay $t: no seeds (../shared/data missing?)"
        continue
    fi
    # shellcheck disable=SC2086
    kept=""; [ -d "tests/fuzz/crashers/$t" ] && kept="tests/fuzz/crashers/$t"
    # shellcheck disable=SC2086
    out=$("$bin" $list $kept 2>&1); rc=$?
    n=$(printf '%s\n' "$out" | sed -n 's/^\([0-9]*\) inputs$/\1/p')
    check "replay $t: $n seeds and crashers, no sanitizer report" '[ "$rc" = 0 ] && [ -n "$n" ] && ! printf "%s" "$out" | grep -q "ERROR: [A-Za-z]*Sanitizer\|runtime error"'
    [ "$rc" = 0 ] || printf '%s\n' "$out" | tail -30
done
checks_done
