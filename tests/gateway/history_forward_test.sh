#!/usr/bin/env bash
# The gateway as built, forwarding its history ([history] forward_to) to a real PostgreSQL server
# this test starts (start_postgres), with simulated devices on virtual lines:
# - --check connects once: a missing database and a wrong password are each named with what to
#   do, and a right password passes and creates the tables;
# - at run time a wrong password is a logged retry (once), never a stop: polling goes on, and once
#   the password file is right (SIGHUP) every row recorded meanwhile arrives;
# - the historian's tables dropped under a forwarding gateway are made again by its next batch,
#   with no reconnect; emptied with their ids started again and another gateway's series made
#   under the ids the first one had learnt, the first one's rows still go under its own series;
# - two gateways of different names forward into one database, and both appear in it;
# - `loopwire history` reads a gateway's history from the historian and from its own file;
# - row by row, each gateway's file against the historian: every row forwarded (not waiting in
#   the outbox) since the ids were started again is there once, under its own gateway's series,
#   and the historian holds no row its gateway's file does not;
# - the audit of writes and reloads (a `loopwire write` through the Modbus TCP front, the
#   password's SIGHUP) arrives in loopwire_writes as the gateway's file has it.
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

# The tables dropped while north forwards: its next batch makes them again, on the same connection.
pg_sql "DROP TABLE loopwire_samples, loopwire_minutes, loopwire_series, loopwire_schema_version" plant
wait_for 60 "north's rows in PostgreSQL after its tables were dropped" arrived north
# Emptied with the ids started again, and south's series made in the same transaction under the
# ids north learnt for its own (the same device and parameters, in the same order): north's next
# batches must learn its ids again, not file its rows under south's series.
pg_sql "BEGIN;
CREATE TEMPORARY TABLE north_names AS SELECT id, device, parameter, unit FROM loopwire_series WHERE gateway = 'north';
TRUNCATE loopwire_samples, loopwire_minutes, loopwire_series RESTART IDENTITY;
INSERT INTO loopwire_series(gateway, device, parameter, unit) SELECT 'south', device, parameter, unit FROM north_names ORDER BY id;
COMMIT" plant
cut=$(date +%s%3N)
expect_equal "$(pg_sql "SELECT count(*) > 0 FROM loopwire_series WHERE gateway = 'south'" plant)" t "south's series under north's ids"
arrived_after_cut() {  # GATEWAY ROWS
  (($(pg_sql "SELECT count(*) FROM loopwire_samples s JOIN loopwire_series n ON n.id = s.series_id WHERE n.gateway = '$1' AND s.t > $cut" plant) > $2))
}
wait_for 60 "north's rows in PostgreSQL after the ids were started again" arrived_after_cut north 3
expect "north's log says its tables or series changed" grep -q "the historian's tables or series changed" "$WORK_DIR/north.log"

# A second gateway of another name, into the same database.
write_config "$WORK_DIR/south.toml" south plant "$WORK_DIR/right.password"
start_background south.log timeout 200 "$loopwire" gateway --config "$WORK_DIR/south.toml"
south=$LAST_PID
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
# Enough rows of both to compare (heartbeats every second, of each polled value).
wait_for 120 "50 of north's rows after the cut in PostgreSQL" arrived_after_cut north 50
wait_for 120 "50 of south's rows in PostgreSQL" arrived_after_cut south 50
# The audit goes to the historian too: north's reload (the password file's SIGHUP above) and a
# write by `loopwire write` through north's Modbus TCP front, each once, as north's file has them.
north_port=$(wait_for_log north.log 'Modbus TCP on 127\.0\.0\.1 \(listening on port ([0-9]+)\)' 5)
check cli-write-through-the-front 0 "" "$loopwire" write --link "tcp://127.0.0.1:$north_port" --device tc10@3 SP=150
historian_writes() {
  pg_sql "SELECT string_agg(front || '|' || peer || '|' || device || '|' || parameter || '|' || new_value || '|' || outcome, E'\n' ORDER BY t, local_id) FROM loopwire_writes WHERE gateway = '$1'" plant
}
local_writes() {
  sqlite3 "$WORK_DIR/$1.db" "SELECT group_concat(front || '|' || peer || '|' || device || '|' || parameter || '|' || new_value || '|' || outcome, char(10)) FROM (SELECT * FROM writes ORDER BY t, id)"
}
write_forwarded() { [[ $(historian_writes north) == *"modbus_tcp|"*"|oven|function "*"|confirmed"* ]]; }
wait_for 60 "north's audited write in PostgreSQL" write_forwarded
expect_equal "$(historian_writes north)" "$(local_writes north)" "north's audit rows in the historian, as in its file"
expect_equal "$(historian_writes north | cut -d'|' -f1,2,6 | head -n 1)" "reload|SIGHUP|confirmed" "north's reload, audited"
expect_equal "$(pg_sql "SELECT count(*) FROM loopwire_writes WHERE gateway = 'south'" plant)" 0 "south's audit rows (none)"
# Row by row, once both have stopped: each gateway's rows in its file (those stamped after the cut
# for north: the ones before went with the dropped and emptied tables), less those still waiting
# in its outbox, are in the historian once, under its own gateway's series; and every row the
# historian holds under a gateway's series is one of that gateway's file.
kill -TERM "$north" "$south"
wait "$north" "$south" 2>/dev/null
row_key="r.device || '|' || r.parameter || '|' || r.unit || '|' || s.t || '|' || coalesce(CAST(round(s.value * 1000) AS INTEGER), '-') || '|' || coalesce(s.text, '-') || '|' || coalesce(s.status, 'ok')"
local_rows() {  # GATEWAY FROM_MS
  sqlite3 "$WORK_DIR/$1.db" "SELECT $row_key FROM samples s JOIN series r ON r.id = s.series_id WHERE s.t > $2" | LC_ALL=C sort
}
waiting_rows() {  # GATEWAY
  sqlite3 "$WORK_DIR/$1.db" "SELECT $row_key FROM outbox o JOIN samples s ON s.series_id = o.series_id AND s.t = o.t JOIN series r ON r.id = s.series_id" | LC_ALL=C sort
}
historian_rows() {  # GATEWAY
  pg_sql "SELECT n.device || '|' || n.parameter || '|' || n.unit || '|' || s.t || '|' || coalesce((round(s.value * 1000)::bigint)::text, '-') || '|' || coalesce(s.text, '-') || '|' || coalesce(s.status, 'ok') FROM loopwire_samples s JOIN loopwire_series n ON n.id = s.series_id WHERE n.gateway = '$1'" plant | LC_ALL=C sort
}
for gateway in north south; do
  from=0
  [[ $gateway == north ]] && from=$cut
  local_rows "$gateway" "$from" >"$WORK_DIR/$gateway.local"
  local_rows "$gateway" 0 >"$WORK_DIR/$gateway.all"
  waiting_rows "$gateway" >"$WORK_DIR/$gateway.waiting"
  historian_rows "$gateway" >"$WORK_DIR/$gateway.held"
  LC_ALL=C comm -23 "$WORK_DIR/$gateway.local" "$WORK_DIR/$gateway.waiting" >"$WORK_DIR/$gateway.expected"
  missing=$(LC_ALL=C comm -23 "$WORK_DIR/$gateway.expected" "$WORK_DIR/$gateway.held" | wc -l)
  duplicated=$(uniq -d "$WORK_DIR/$gateway.held" | wc -l)
  misfiled=$(LC_ALL=C comm -23 <(uniq "$WORK_DIR/$gateway.held") "$WORK_DIR/$gateway.all" | wc -l)
  echo "$gateway: $(wc -l <"$WORK_DIR/$gateway.expected") rows expected, $(wc -l <"$WORK_DIR/$gateway.held") held;" \
    "$missing missing, $duplicated duplicated, $misfiled misfiled; $(wc -l <"$WORK_DIR/$gateway.waiting") waiting"
  expect_equal "$missing/$duplicated/$misfiled" 0/0/0 "$gateway's rows missing/duplicated/misfiled"
  (($(wc -l <"$WORK_DIR/$gateway.expected") >= 50)) || fail "$gateway: too few rows to compare"
done
finish
