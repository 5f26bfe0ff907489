#!/bin/sh
# make check: every fuzz target's seeds with each of their allocations refused in turn
# (curl's torture tests): tests/fuzz/replay.sh --torture says how.
exec "$(dirname "$0")/replay.sh" --torture
