#!/bin/sh
# The trim-point budget of an IGES part (issue 48, finding 2): a 16 KB file whose 40 trimmed surfaces
# share one composite loop of 2.8 M points once took 2.3 GB and 93 s. What every surface's loops
# will hold is counted from what the file declares before any loop is built, each use of a shared
# curve counted again, and a part over the budget is a quick 422 naming the budget and the figure.
# The real parts stay within it: tests/api/iges.sh renders and measures them. A part within it whose
# loops crowd together is refused by /volume before their points are matched (SHELL_MAX_TESTS).
. "$(dirname "$0")/lib.inc"

python3 tests/tools/iges_hostile.py "$T/shared40.igs" 40
python3 tests/tools/iges_hostile.py "$T/nested.igs" 1 15
python3 tests/tools/iges_hostile.py "$T/once.igs" 1
size=$(wc -c <"$T/shared40.igs")
check "the hostile part is as small as the finding's: $size bytes" '[ "$size" -lt 17000 ]'

start_daemon "$T/d" --threads 2 || exit 1

# post PATH FILE: the status (body in $T/body) and, in $secs, how long the answer took
post() {
    t0=$(date +%s.%N)
    code=$(status POST "$1" --max-time 60 --data-binary @"$2")
    secs=$(python3 -c "import sys; print('%.1f' % (float(sys.argv[2]) - float(sys.argv[1])))" "$t0" "$(date +%s.%N)")
}
quick() { python3 -c "import sys; sys.exit(float(sys.argv[1]) >= 10)" "$secs"; }
budget_422() { [ "$code" = 422 ] && is_problem 422 && grep -q 'budget of [0-9]* trim points' "$T/body" && grep -q '"pointer":"D[0-9]*"' "$T/body"; }

post "/render?format=iges&width=32&height=32" "$T/shared40.igs"
[ -n "${IGES_VERBOSE:-}" ] && echo "render: $code in $secs s: $(cat "$T/body")"
check "40 surfaces sharing a 2.8 M-point loop: /render 422 naming the budget and a surface ($code in $secs s)" 'budget_422'
check "... answered in $secs s (well under 10)" 'quick'
figure=$(sed -n 's/.* come to \([0-9]*\) points.*/\1/p' "$T/body")
check "... the figure given ($figure points) is what the uses so far come to, each a 2.8 M-point loop" \
    '[ -n "$figure" ] && [ "$figure" -ge 2800000 ]'
post "/volume?format=iges" "$T/shared40.igs"
check "/volume refuses it the same way ($code in $secs s)" 'budget_422 && quick'
post "/render?format=iges&width=32&height=32" "$T/nested.igs"
[ -n "${IGES_VERBOSE:-}" ] && echo "nested: $code in $secs s: $(cat "$T/body")"
check "one loop through 15 composites, each naming the one below twice (2^15 uses): 422 at once ($code in $secs s)" \
    'budget_422 && quick'
post "/render?format=iges&width=32&height=32" "$T/once.igs"
check "the same loop used once is within the budget: not refused for it ($code in $secs s)" \
    '! grep -q "budget of" "$T/body" && { [ "$code" = 200 ] || [ "$code" = 422 ]; }'
post "/volume?format=iges" "$T/once.igs"
[ -n "${IGES_VERBOSE:-}" ] && echo "volume once: $code in $secs s: $(cat "$T/body")"
check "... but /volume of it, whose 2.8 M boundary points crowd into few cells (minutes of matching): 422 naming the tests it would take, before them ($code in $secs s)" \
    '[ "$code" = 422 ] && is_problem 422 && grep -q "crowd together: matching their points would take some [0-9.e+]* tests, over the limit of 1e+09" "$T/body"'
check "the daemon is up after them" 'alive'
finish
