#!/bin/sh
# Liveness, readiness and the Prometheus metrics, as a monitoring probe would read them.
set -eu
: "${SURFD_URL:=http://127.0.0.1:8080}"
curl -sSf "$SURFD_URL/livez"
curl -sSf "$SURFD_URL/readyz"
curl -sSf ${SURFD_TOKEN:+-H "Authorization: Bearer $SURFD_TOKEN"} "$SURFD_URL/metrics" | grep -E '^surfd_(jobs|queue_depth)'
