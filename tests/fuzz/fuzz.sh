#!/bin/sh
# make fuzz: each libFuzzer target in build/fuzz for
# FUZZ_SECONDS seconds, from its seeds (seeds.inc) and the corpus it grew before (build/fuzz/corpus).
# A crash, leak, timeout or sanitizer report fails the target and leaves the input in
# build/fuzz/crashes/NAME: keep it as a regression input in tests/fuzz/crashers/NAME once fixed.
set -u
cd "$(dirname "$0")/../.." || exit 1
. tests/check.inc
. tests/fuzz/seeds.inc
S=${FUZZ_SECONDS:-60}
# a value length a decoder trusts (DCMTK allocates what a DICOM element claims, up to 4 GB, before
# reading it) fails as an allocation, not as minutes of shadow-memory writes
export ASAN_OPTIONS="${ASAN_OPTIONS:-max_allocation_size_mb=512:allocator_may_return_null=1:malloc_fill_byte=1}"
for src in tests/fuzz/fuzz_${FUZZ_ONLY:-*}.c; do # FUZZ_ONLY=NAME: one target
    t=${src#tests/fuzz/fuzz_}; t=${t%.c}; bin=build/fuzz/$t
    [ -x "$bin" ] || { bad "fuzz $t: $bin is not built (clang and libclang-rt-14-dev)"; continue; }
    mkdir -p "build/fuzz/corpus/$t" "build/fuzz/crashes/$t"
    # seeds past 256 KB (whole clinical structure sets) run a few times a second under ASan: replay.sh has them
    list=$(seeds "$t" | while read -r f; do [ "$(wc -c <"$f")" -le 262144 ] && echo "$f"; done | tr '\n' ',' | sed 's/,$//')
    kept=""; [ -d "tests/fuzz/crashers/$t" ] && kept="tests/fuzz/crashers/$t" # a target may have none yet
    # an input is at most 64 KB and a hang at 20 s; fuzz_frames' inputs as long as its crashers
    # (counts of items walked once: 30 000 per-frame items, fragments, 13 000 segments, under
    # 256 KB each, whole rather than cut) and a hang at 10 s (such counts walked quadratically took
    # minutes in a few MB)
    len=65536 to=20
    case $t in frames) len=262144 to=10 ;; esac
    # shellcheck disable=SC2086
    "$bin" -max_total_time="$S" -max_len="$len" -timeout="$to" -rss_limit_mb=4096 -print_final_stats=1 \
        -seed_inputs="$list" -artifact_prefix="build/fuzz/crashes/$t/" "build/fuzz/corpus/$t" \
        $kept >"build/fuzz/$t.log" 2>&1
    rc=$?
    runs=$(sed -n 's/^stat::number_of_executed_units: *//p' "build/fuzz/$t.log" | tail -n 1)
    check "fuzz $t: ${runs:-?} inputs in ${S}s, no crash" '[ "$rc" = 0 ]'
    [ "$rc" = 0 ] || { grep -A25 -m1 "ERROR\|==ERROR\|runtime error\|deadly signal\|timeout" "build/fuzz/$t.log"; ls "build/fuzz/crashes/$t"; }
done
checks_done
