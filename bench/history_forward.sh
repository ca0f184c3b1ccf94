#!/bin/bash
# The history's forwarding to PostgreSQL, two figures, on a server this script starts
# (start_postgres: a new cluster on a Unix socket, fsync off for both sides alike):
#
# 1. Ingest rows/s: the forwarder shipping 200,000 waiting rows (50 parameters) from the local
#    file into the historian (partitioned samples, primary key, the minute rollup upserted in the
#    same transaction), against psql's \copy of the same rows into a plain table with the same
#    primary key, in the same run; each side's tables are made before its time starts. The two
#    take turns, RUNS times (LOOPWIRE_BENCH_RUNS, default 3), each into a database of its own;
#    the figures are the medians, so that one turn slowed by the machine's other work does not
#    decide. The goal is 0.7 or more.
# 2. A local buffer of 1,000,000 rows forwarded: the time taken. The goal is under 60 s.
#
# Usage: bench/history_forward.sh BUILD_DIR [ROWS]    (ROWS for the first figure, default 200000)
# LOOPWIRE_FORWARD_BATCH=N sets the rows one transaction ships (the forwarder's default is 20000).
#
# Builds nothing: BUILD_DIR must hold bench/history_forward.
set -euo pipefail

if [[ $# -lt 1 || $# -gt 2 ]]; then
    echo "usage: $0 BUILD_DIR [ROWS]" >&2
    exit 2
fi
readonly BUILD_DIR=$1 ROWS=${2:-200000}
readonly FORWARD=$BUILD_DIR/bench/history_forward
[[ -x $FORWARD ]] || { echo "$FORWARD is missing: build the history_forward target" >&2; exit 2; }
source "$(dirname "$0")/../tests/support/test_lib.sh"
start_postgres
conninfo="host=$PG_HOST port=$PG_PORT dbname=postgres user=postgres"

seconds_of() { sed -nE 's/^forwarded [0-9]+ rows in ([0-9.]+) s$/\1/p' "$1"; }

# 1. The forwarder against \copy, the same rows, in turns.
runs=${LOOPWIRE_BENCH_RUNS:-3}
forward_times=() copy_times=()
for ((run = 1; run <= runs; run++)); do
    pg_sql "CREATE DATABASE ingest$run"
    "$FORWARD" "$WORK_DIR/ingest$run.db" "host=$PG_HOST port=$PG_PORT dbname=ingest$run user=postgres" "$ROWS" \
        "$WORK_DIR/rows.csv" >"$WORK_DIR/ingest$run.out"
    forward_times+=("$(seconds_of "$WORK_DIR/ingest$run.out")")
    pg_sql "CREATE TABLE copy_peer(series_id bigint NOT NULL, t bigint NOT NULL, value double precision, text text,
            status text, PRIMARY KEY(series_id, t))" "ingest$run"
    began=$EPOCHREALTIME
    psql -X -q -h "$PG_HOST" -p "$PG_PORT" -U postgres -d "ingest$run" -c "\\copy copy_peer FROM '$WORK_DIR/rows.csv' CSV"
    ended=$EPOCHREALTIME
    copy_times+=("$(python3 -c "print($ended - $began)")")
    expect_equal "$(pg_sql "SELECT count(*) FROM loopwire_samples" "ingest$run")" "$ROWS" "rows in the historian"
done
python3 -c "
import statistics
rows = $ROWS
forward = statistics.median([${forward_times[*]/%/,}])
copy = statistics.median([${copy_times[*]/%/,}])
print(f'ingest ($runs turns, medians): forwarder {rows / forward:.0f} rows/s, psql \\\\copy {rows / copy:.0f} rows/s: '
      f'ratio {copy / forward:.2f} (goal >= 0.7)')"

# 2. A buffer of a million rows, forwarded into a database of its own.
pg_sql "CREATE DATABASE million"
"$FORWARD" "$WORK_DIR/million.db" "host=$PG_HOST port=$PG_PORT dbname=million user=postgres" 1000000 /dev/null >"$WORK_DIR/million.out"
printf 'a buffer of 1,000,000 rows forwarded in %.1f s (goal < 60 s)\n' "$(seconds_of "$WORK_DIR/million.out")"
