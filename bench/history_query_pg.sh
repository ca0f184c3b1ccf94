#!/bin/bash
# The historian's answer to a month's trend: 30 days of one sample a second of one
# series (2,592,000 rows) in the PostgreSQL historian, queried into 500 buckets as
# /api/history?gateway= asks it; the whole minutes come from the per-minute rollup. The goal is
# under 200 ms. On a server this script starts (start_postgres: a new cluster on a Unix socket).
#
# Usage: bench/history_query_pg.sh BUILD_DIR [DAYS]    (DAYS default 30)
#
# Builds nothing: BUILD_DIR must hold bench/history_query_pg.
set -euo pipefail

if [[ $# -lt 1 || $# -gt 2 ]]; then
    echo "usage: $0 BUILD_DIR [DAYS]" >&2
    exit 2
fi
readonly BUILD_DIR=$1 DAYS=${2:-30}
readonly QUERY=$BUILD_DIR/bench/history_query_pg
[[ -x $QUERY ]] || { echo "$QUERY is missing: build the history_query_pg target" >&2; exit 2; }
source "$(dirname "$0")/../tests/support/test_lib.sh"
start_postgres
"$QUERY" "host=$PG_HOST port=$PG_PORT dbname=postgres user=postgres" "$DAYS"
