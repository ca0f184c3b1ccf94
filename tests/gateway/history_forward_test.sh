#!/usr/bin/env bash
# The gateway as built, forwarding its history ([history] forward_to) to a real PostgreSQL server
# this test starts (start_postgres), with simulated devices on virtual lines:
# - --check connects once: a missing database and a wrong password are each named with what to
#   do, and a right password passes and creates the tables;
# - at run time a wrong password is a logged retry (once), never a stop: polling goes on, and once
#   the password file is right (SIGHUP) every row recorded meanwhile arrives;
# - two gateways of different names forward into one database, and both appear in it;
# - `loopwire history` reads a gateway's history from the historian and from its own file.
set -u
loopwire=${1:?usage: history_forward_test.sh path/to/loopwire}
source "$(dirname "$0")/../support/test_lib.sh"

start_postgres "local all pwuser scram-sha-256
local all all trust"
pg_sql "CREATE ROLE pwuser LOGIN PASSWORD 'right'"

write_config() {  # FILE GATEWAY DATABASE PASSWORD_FILE
  cat >"$1" <<TOML
[gateway]
name = "$2"

[[lines]]
name = "furnace"
link = "rtu:virtual?baud=19200"

[[lines.devices]]
name = "oven"
device = "tc10@3"
poll = "200ms"

[modbus_tcp]
listen = "127.0.0.1:0"

[history]
database = "$2.db"
heartbeat = "1s"
forward_to = "postgresql://pwuser@/$3?host=$PG_HOST&port=$PG_PORT"
password_file = "$4"
TOML
}
printf 'wrong\n' >"$WORK_DIR/wrong.password"
printf 'right\n' >"$WORK_DIR/right.password"
chmod 600 "$WORK_DIR"/*.password

write_config "$WORK_DIR/north.toml" north plant "$WORK_DIR/right.password"
check check-missing-database 3 'database "plant" does not exist; create the database (createdb)' \
  "$loopwire" gateway --config "$WORK_DIR/north.toml" --check
pg_sql "CREATE DATABASE plant OWNER pwuser"
write_config "$WORK_DIR/north.toml" north plant "$WORK_DIR/wrong.password"
check check-wrong-password 3 'password authentication failed for user "pwuser"; check [history] password_file' \
  "$loopwire" gateway --config "$WORK_DIR/north.toml" --check
write_config "$WORK_DIR/north.toml" north plant "$WORK_DIR/right.password"
check check-right-password 0 "history:" "$loopwire" gateway --config "$WORK_DIR/north.toml" --check
expect_equal "$(pg_sql "SELECT version FROM loopwire_schema_version" plant)" 2 "schema version after --check"

# At run time a wrong password pauses forwarding, and polling and the local history go on.
write_config "$WORK_DIR/north.toml" north plant "$WORK_DIR/wrong.password"
start_background north.log timeout 200 "$loopwire" gateway --config "$WORK_DIR/north.toml"
north=$LAST_PID
wait_for_log north.log '(forwarding paused)' 120 >/dev/null
rows_waiting() { (($(sqlite3 "$WORK_DIR/north.db" "SELECT count(*) FROM outbox" 2>/dev/null || echo 0) > 3)); }
wait_for 60 "rows waiting in the outbox" rows_waiting
kill -0 "$north" || fail "the gateway stopped on a wrong password"
expect_equal "$(grep -c 'forwarding paused' "$WORK_DIR/north.log")" 1 "outage log lines"

# The right password (SIGHUP reloads it and reopens the history): everything waiting arrives.
write_config "$WORK_DIR/north.toml" north plant "$WORK_DIR/right.password"
kill -HUP "$north"
wait_for_log north.log '(forwarding to postgresql pwuser@)' 120 >/dev/null
forwarded() { pg_sql "SELECT count(*) FROM loopwire_samples s JOIN loopwire_series n ON n.id = s.series_id WHERE n.gateway = '$1'" plant; }
arrived() { (($(forwarded "$1") > 3)); }
wait_for 60 "north's rows in PostgreSQL" arrived north

# A second gateway of another name, into the same database.
write_config "$WORK_DIR/south.toml" south plant "$WORK_DIR/right.password"
start_background south.log timeout 200 "$loopwire" gateway --config "$WORK_DIR/south.toml"
wait_for 120 "south's rows in PostgreSQL" arrived south
expect_equal "$(pg_sql "SELECT string_agg(DISTINCT gateway, ',' ORDER BY gateway) FROM loopwire_series" plant)" "north,south" \
  "gateways in the historian"
# `loopwire history` reads any gateway's history from the historian, and a gateway's own file.
historian="postgresql://postgres@/plant?host=$PG_HOST&port=$PG_PORT"
check history-cli-historian 0 "parameter,unit,time,min,max,mean,count,kind,until" \
  "$loopwire" history --database "$historian" --gateway south --device oven --from -1h --format csv
check history-cli-historian-rows 0 "measured_value" \
  "$loopwire" history --database "$historian" --gateway south --device oven --parameters measured_value
check history-cli-needs-gateway 2 "--gateway NAME is required with a PostgreSQL database" \
  "$loopwire" history --database "$historian" --device oven
check history-cli-unknown-gateway 2 'the historian has no device "oven" of gateway "west"' \
  "$loopwire" history --database "$historian" --gateway west --device oven
check history-cli-file 0 "measured_value" "$loopwire" history --database "$WORK_DIR/north.db" --device oven --format csv
# Every row the local file holds reached the historian once, or still waits in its outbox.
kill -TERM "$north"
wait "$north" 2>/dev/null
local_rows=$(sqlite3 "$WORK_DIR/north.db" "SELECT count(*) FROM samples")
waiting=$(sqlite3 "$WORK_DIR/north.db" "SELECT count(*) FROM outbox")
expect_equal "$(( $(forwarded north) + waiting ))" "$local_rows" "north's rows: forwarded + waiting = recorded"
finish
