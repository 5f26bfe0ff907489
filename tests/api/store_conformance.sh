#!/bin/sh
# The store conformance suite (tests/daemon/test_store.c) against PostgreSQL, a throwaway cluster:
# held to store.h's diagram directly, as make check holds the embedded SQLite store (issue 43, 8).
. "$(dirname "$0")/lib.inc"
. tests/tools/pg.inc
trap 'pg_stop; rm -rf "$T"' EXIT
BIN=build/tests/daemon/test_store
[ -x "$BIN" ] || { bad "$BIN is not built"; checks_done; exit 1; }
chmod 755 "$T" # the cluster's owner (nobody, under root) reaches its directory inside
pg_start "$T/pg" || { bad "PostgreSQL would not start"; checks_done; exit 1; }
STORE_TARGET="$PG_URI" "$BIN" >"$T/pg.out" 2>&1; rc=$?
check "PostgreSQL: $(tail -n 1 "$T/pg.out")" '[ "$rc" = 0 ] && grep -q "^store: postgresql" "$T/pg.out"'
[ "$rc" = 0 ] || cat "$T/pg.out"
checks_done
