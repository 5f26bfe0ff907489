#!/bin/sh
# api/openapi.yaml against a real OpenAPI linter: @redocly/cli (npm, pinned), installed into build/npm
# on first use. Errors fail the check; the linter's style warnings (operationId, license) are reported.
set -u
cd "$(dirname "$0")/../.." || exit 1
. tests/check.inc
REDOCLY_VERSION=2.77.0
N=build/npm
R=$N/node_modules/.bin/redocly
if [ ! -x "$R" ]; then
    mkdir -p "$N"
    npm install --silent --no-audit --no-fund --prefix "$N" "@redocly/cli@$REDOCLY_VERSION" >"$N/install.log" 2>&1 ||
        { bad "npm could not install @redocly/cli@$REDOCLY_VERSION:"; tail -5 "$N/install.log"; }
fi
if [ -x "$R" ]; then
    REDOCLY_TELEMETRY=off REDOCLY_SUPPRESS_UPDATE_NOTICE=true "$R" lint api/openapi.yaml --format=stylish >"$N/lint.log" 2>&1
    rc=$?
    check "openapi.yaml passes redocly lint (no errors)" '[ "$rc" = 0 ] && grep -q "is valid" "$N/lint.log"'
    [ "$rc" = 0 ] || grep -E " error " "$N/lint.log"
    echo "redocly: $(grep -c " warning " "$N/lint.log") style warnings"
fi
checks_done
