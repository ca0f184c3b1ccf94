#!/usr/bin/env bash
# Grafana-ready history: two gateways (north, south) forward their values to a real PostgreSQL;
# every SQL query of docs/grafana.md and of the dashboard packaging/grafana/loopwire.json (its
# panels and its variables) is run with Grafana's macros ($__timeFilter, $__unixEpochFrom/To)
# and the dashboard's variables expanded as Grafana expands them (grafana_queries.py), and
# answers rows of both gateways from the view loopwire_values. The local file's view answers too.
set -u
loopwire=${1:?usage: grafana_view_test.sh path/to/loopwire}
source "$(dirname "$0")/../support/test_lib.sh"
command -v psql >/dev/null || skip "psql is not installed (Debian package postgresql-client-15)"
command -v sqlite3 >/dev/null || skip "sqlite3 is not installed (Debian package sqlite3)"
top=$(cd "$(dirname "$0")/../.." && pwd)

start_postgres
pg_sql "CREATE DATABASE plant"

start_gateway() {  # NAME
  cat >"$WORK_DIR/$1.toml" <<TOML
[gateway]
name = "$1"

[[lines]]
name = "furnace"
link = "rtu:virtual?baud=19200"

[[lines.devices]]
name = "oven"
device = "tc10@3"
poll = "200ms"
parameters = ["measured_value", "set_point", "control_state"]

[modbus_tcp]
enabled = false

[history]
database = "$WORK_DIR/$1.db"
heartbeat = "1s"
forward_to = "postgresql://postgres@/plant?host=$PG_HOST&port=$PG_PORT"
TOML
  start_background "$1.log" timeout 120 "$loopwire" gateway --config "$WORK_DIR/$1.toml"
}
start_gateway north
start_gateway south
# (The view is there once a gateway has connected; until then the count is 0.)
arrived() { (($(pg_sql "SELECT count(DISTINCT gateway) FROM loopwire_values WHERE value IS NOT NULL" plant 2>/dev/null || echo 0) == 2)); }
wait_for 60 "both gateways' values in the historian's view" arrived
# A minute's rollup is written once its minute has samples; the queries below need one of each.
wait_for 90 "a minute of rollup from both" bash -c \
  "(( \$(psql -X -qAt -h '$PG_HOST' -p '$PG_PORT' -U postgres -d plant -c 'SELECT count(DISTINCT n.gateway) FROM loopwire_minutes m JOIN loopwire_series n ON n.id = m.series_id') == 2 ))"

expect view-has-a-timestamp bash -c "[[ \$(psql -X -qAt -h '$PG_HOST' -p '$PG_PORT' -U postgres -d plant -c \"SELECT pg_typeof(time) FROM loopwire_values LIMIT 1\") == 'timestamp with time zone' ]]"
expect view-says-ok-not-null bash -c "(( \$(psql -X -qAt -h '$PG_HOST' -p '$PG_PORT' -U postgres -d plant -c \"SELECT count(*) FROM loopwire_values WHERE status IS NULL\") == 0 ))"

if /usr/bin/python3 "$(dirname "$0")/grafana_queries.py" "$top/docs/grafana.md" "$top/packaging/grafana/loopwire.json" \
  "$PG_HOST" "$PG_PORT" plant >"$WORK_DIR/queries.out" 2>&1; then
  count_pass
else
  count_failure grafana-queries "$WORK_DIR/queries.out"
fi
cat "$WORK_DIR/queries.out"

# The local file's view, for Grafana's SQLite data source and the sqlite3 shell.
expect local-view bash -c "sqlite3 '$WORK_DIR/north.db' \"SELECT time, device, parameter, status FROM loopwire_values WHERE value IS NOT NULL LIMIT 1\" | grep -qE '^20[0-9-]+T[0-9:.]+Z\|oven\|[a-z_]+\|ok$'"
finish
