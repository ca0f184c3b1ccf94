#!/usr/bin/env bash
# `loopwire history` on a gateway's own history file, as a user runs it after the gateway has
# recorded a while: the table and the CSV have the buckets, and for a window that starts after
# the last row, the value in force at its start (the last value recorded before it, no bucket),
# as GET /api/history's `before` has it (docs/DESIGN.md, history). A file that is not a history
# is refused, saying so.
set -u
loopwire=${1:?usage: history_command_test.sh path/to/loopwire}
source "$(dirname "$0")/../support/test_lib.sh"

cat >"$WORK_DIR/plant.toml" <<TOML
[[lines]]
name = "line"
link = "rtu:virtual?baud=115200&parity=none"

[[lines.devices]]
name = "oven"
device = "tc10@1"
poll = "200ms"
parameters = ["measured_value", "set_point"]

[modbus_tcp]
enabled = false

[history]
database = "$WORK_DIR/plant.db"
heartbeat = "1s"
TOML
database=$WORK_DIR/plant.db

start_background gateway.log timeout 120 "$loopwire" gateway --config "$WORK_DIR/plant.toml"
gateway=$LAST_PID
measured_rows() {
  sqlite3 "$database" "SELECT count(*) FROM samples JOIN series ON series.id = series_id
                       WHERE device = 'oven' AND parameter = 'measured_value'" 2>/dev/null
}
recorded() { (( $(measured_rows || echo 0) >= 2 )); }
wait_for 60 "two measured_value rows in $database" recorded
kill -TERM "$gateway"
wait "$gateway" 2>/dev/null

check table 0 "measured_value" "$loopwire" history --database "$database" --device oven --from -1h
check table-unit 0 "°C" "$loopwire" history --database "$database" --device oven --from -1h --parameters measured_value
check csv-header 0 "parameter,unit,time,min,max,mean,count,kind,until" \
  "$loopwire" history --database "$database" --device oven --format csv
check csv-bucket 0 ",bucket," "$loopwire" history --database "$database" --device oven --format csv --parameters set_point

# A window between the last two rows of measured_value (from 1 ms after the one before the last
# to 1 ms before the last): no bucket in it, and the value then in force is the one recorded at
# the earlier row. Not a window after the last row: the gateway's stop may come within 1 ms of it,
# and then the stop's gap is what is in force there.
rows=$(sqlite3 -separator ' ' "$database" "SELECT t, printf('%g', value) FROM samples JOIN series ON series.id = series_id
                                             WHERE device = 'oven' AND parameter = 'measured_value' ORDER BY t DESC LIMIT 2")
read -r -d '' later _ last value <<<"$rows"
[[ ${last:-} =~ ^[0-9]+$ && $later =~ ^[0-9]+$ ]] || fail "fewer than two measured_value rows in $database: '$rows'"
(( later - last >= 3 )) || fail "the last two rows are $((later - last)) ms apart (poll 200ms): '$rows'"
iso() { date -u -d "@$(($1 / 1000)).$(printf %03d $(($1 % 1000)))" +%Y-%m-%dT%H:%M:%S.%3NZ; }
from=$(iso $((last + 1)))
to=$(iso $((later - 1)))
check csv-before 0 "measured_value,°C,$(iso "$last"),$value,$value,$value,,before," \
  "$loopwire" history --database "$database" --device oven --format csv --from "$from" --to "$to"
out=$("$loopwire" history --database "$database" --device oven --format csv --from "$from" --to "$to" --parameters measured_value)
expect csv-before-only test "$(grep -c ',bucket,' <<<"$out")" -eq 0
check table-before 0 "in force at the start" \
  "$loopwire" history --database "$database" --device oven --from "$from" --to "$to" --parameters measured_value

# A file that is not a history: said so, exit 2 (not a failed query naming a table, exit 3), by
# `history` and by the gateway's --check, which used to pass it and let the start fail.
echo secret >"$WORK_DIR/not-a-database"
sqlite3 "$WORK_DIR/other.db" "CREATE TABLE notes(text)"
check history-of-a-text-file 2 "cannot be read as an SQLite database" \
  "$loopwire" history --database "$WORK_DIR/not-a-database" --device oven
check history-of-another-database 2 "is an SQLite database of another program, not a loopwire history" \
  "$loopwire" history --database "$WORK_DIR/other.db" --device oven
sed "s|^database = .*|database = \"$WORK_DIR/not-a-database\"|" "$WORK_DIR/plant.toml" >"$WORK_DIR/not-a-database.toml"
check check-refuses-a-text-file-as-history 2 "history.database: history database $WORK_DIR/not-a-database: cannot be read" \
  "$loopwire" gateway --config "$WORK_DIR/not-a-database.toml" --check
check check-takes-the-recorded-history 0 "history" "$loopwire" gateway --config "$WORK_DIR/plant.toml" --check
finish
