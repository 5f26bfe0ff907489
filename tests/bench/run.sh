#!/bin/sh
# make bench: runs tests/bench/bench.py (surfd's methods and POV-Ray on the same machine, in the
# same run) and rewrites tests/bench/RESULTS.md. Never part of make test: timings are noisy.
set -eu
cd "$(dirname "$0")/../.."
exec python3 tests/bench/bench.py "$@"
