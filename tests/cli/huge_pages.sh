#!/bin/sh
# The release build starts itself again with glibc's huge pages for its heaps
# (GLIBC_TUNABLES=glibc.malloc.hugetlb=1, daemon/main.c: a mesh's first touch faulted every 4 KB)
# under the same process id, keeping the tunables it was given; an operator's own setting of that
# tunable (=0: small pages) is left as it is.
. "$(dirname "$0")/lib.inc"
# serve on a free port until asked to stop; its environment as the kernel has it after the start
# (glibc cuts the tunables' string at its colons in place as it reads it: one a line here)
environ_of() {
    env "$@" $S serve --listen 127.0.0.1:0 --data-dir "$T/d" >"$T/log" 2>&1 &
    pid=$!
    for _ in $(seq 100); do grep -q "listening on" "$T/log" 2>/dev/null && break; sleep 0.1; done
    tr '\0:' '\n\n' <"/proc/$pid/environ" | grep -E '^(GLIBC_TUNABLES=)?glibc\.' | sed 's/^GLIBC_TUNABLES=//' >"$T/env"
    kill "$pid"; wait "$pid" 2>/dev/null
}
environ_of -u GLIBC_TUNABLES
check "serve: started again (the same pid) with glibc.malloc.hugetlb=1" \
    'grep -q "listening on" "$T/log" && [ "$(cat "$T/env")" = "glibc.malloc.hugetlb=1" ]'
environ_of GLIBC_TUNABLES=glibc.malloc.arena_max=2
check "... the tunables it was given kept before it" '[ "$(cat "$T/env" | tr "\n" " ")" = "glibc.malloc.arena_max=2 glibc.malloc.hugetlb=1 " ]'
environ_of GLIBC_TUNABLES=glibc.malloc.hugetlb=0
check "an operator's glibc.malloc.hugetlb=0: left as it is" '[ "$(cat "$T/env")" = "glibc.malloc.hugetlb=0" ]'
checks_done
