#!/bin/sh
# make check: every fuzz target (built with gcc and the sanitizers over tests/fuzz/replay.c) replays
# its seeds and the crashers kept in tests/fuzz/crashers/NAME: each once crashed or hung a decoder.
# With --torture (tests/fuzz/torture.sh), each target's torture build (replay.c -DTORTURE, the
# daemon's allocator wrappers) runs its own seeds once for every allocation they make, with that
# allocation refused (up to 2000 runs an input): every run must end cleanly, without a sanitizer
# report, and give back every byte it took. A target without seeds of its own takes the smallest
# of its shared ones there.
set -u
cd "$(dirname "$0")/../.." || exit 1
. tests/check.inc
. tests/fuzz/seeds.inc
mode=replay
[ "${1:-}" = --torture ] && mode=torture
export ASAN_OPTIONS="${ASAN_OPTIONS:-detect_leaks=1:max_allocation_size_mb=512:allocator_may_return_null=1:malloc_fill_byte=1}" UBSAN_OPTIONS="${UBSAN_OPTIONS:-print_stacktrace=1}"
for src in tests/fuzz/fuzz_*.c; do
    t=${src#tests/fuzz/fuzz_}; t=${t%.c}; bin=build/tests/fuzz/${mode}_$t
    [ -x "$bin" ] || { bad "$mode $t: $bin is not built"; continue; }
    if [ $mode = torture ]; then
        list="tests/fuzz/seeds/$t"
        [ -d "$list" ] || list=$(seeds "$t" | xargs -r ls -S | tail -n 1) # the smallest
        kept=""
    else
        list=$(seeds "$t")
        kept=""; [ -d "tests/fuzz/crashers/$t" ] && kept="tests/fuzz/crashers/$t"
    fi
    if [ -z "$list" ] || { needs_shared "$t" && [ ! -d "$DATA" ]; }; then
        bad "$mode $t: no seeds (../shared/data missing?)"
        continue
    fi
    # shellcheck disable=SC2086
    out=$("$bin" $list $kept 2>&1); rc=$?
    n=$(printf '%s\n' "$out" | sed -n 's/^\([0-9]*\) inputs.*/\1/p')
    runs=$(printf '%s\n' "$out" | sed -n 's/^[0-9]* inputs, \([0-9]*\) runs.*/, \1 runs each with one allocation refused/p')
    check "$mode $t: $n inputs$runs, no sanitizer report" '[ "$rc" = 0 ] && [ -n "$n" ] && ! printf "%s" "$out" | grep -q "ERROR: [A-Za-z]*Sanitizer\|runtime error"'
    [ "$rc" = 0 ] || printf '%s\n' "$out" | tail -30
done
checks_done
