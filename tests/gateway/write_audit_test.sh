#!/usr/bin/env bash
# The audit of writes: a gateway polls a simulated TC10 ("oven") and one nothing answers for
# ("absent"), serves HTTP (with a token), MQTT, Sparkplug B and Modbus TCP, and keeps a history
# file. write_audit_check.py writes once through every front, then a value out of range and a
# write to the silent device, and wants exactly one audit record a write, with the right front,
# peer, old and new values and outcome, from GET /api/audit, `loopwire audit` and the log (at
# notice level). Then two reloads (SIGHUP): a file that does not load and one that adds a
# device, each one row with what changed.
set -u
loopwire=${1:?usage: write_audit_test.sh path/to/loopwire}
source "$(dirname "$0")/../support/test_lib.sh"
python=/usr/bin/python3
here=$(cd "$(dirname "$0")" && pwd)
repo=$(cd "$here/../.." && pwd)
skip() { echo "SKIP: $1 (scripts/setup installs it)"; exit 77; }
[[ -x /usr/sbin/mosquitto ]] || skip "/usr/sbin/mosquitto is not installed (Debian package mosquitto)"
command -v mosquitto_pub >/dev/null || skip "mosquitto_pub is not installed (Debian package mosquitto-clients)"
$python -c 'import paho.mqtt' 2>/dev/null || skip "paho.mqtt is not importable by $python (Debian package python3-paho-mqtt)"
$python -c 'import pymodbus' 2>/dev/null || skip "pymodbus is not importable by $python (Debian package python3-pymodbus)"
command -v protoc >/dev/null || skip "protoc is not installed (Debian package protobuf-compiler)"
$python -c 'import google.protobuf' 2>/dev/null || skip "google.protobuf is not importable by $python (Debian package python3-protobuf)"

protoc --python_out="$WORK_DIR" -I "$repo/src/gateway/sparkplug" "$repo/src/gateway/sparkplug/sparkplug_b.proto" ||
  fail "protoc could not compile src/gateway/sparkplug/sparkplug_b.proto"
export SPARKPLUG_PB_DIR=$WORK_DIR
sparkplug_checker=$here/sparkplug_check.py

pty="$WORK_DIR/ttyA0"
start_background sim.log "$loopwire" simulate --link "rtu:/unused?baud=19200&parity=none" --pty "$pty" \
  --device tc10@3 --duration 170s
wait_for_path "$pty"

start_mosquitto 170
recording=$WORK_DIR/sparkplug.jsonl
start_background recorder.log timeout 170 "$python" "$sparkplug_checker" record --port "$MQTT_PORT" --out "$recording" \
  --duration 165
wait_for_text "$WORK_DIR/recorder.log" "subscribed" 30
touch "$recording"

token_file=$WORK_DIR/token
head -c 24 /dev/urandom | base64 >"$token_file"
chmod 600 "$token_file"
cat >"$WORK_DIR/plant.toml" <<TOML
[[lines]]
name = "furnace-line"
link = "rtu:$pty?baud=19200&parity=none"
timeout = "300ms"

[[lines.devices]]
name = "oven"
device = "tc10@3"
poll = "300ms"

[[lines.devices]]
name = "absent"
device = "tc10@4"
poll = "1s"

[modbus_tcp]
listen = "127.0.0.1:0"

[http]
listen = "127.0.0.1:0"
token_file = "$token_file"

[mqtt]
broker = "mqtt://127.0.0.1:$MQTT_PORT"
writes = true

[sparkplug]
broker = "mqtt://127.0.0.1:$MQTT_PORT"
group_id = "plant"
edge_node_id = "cabinet1"
writes = true

[history]
database = "$WORK_DIR/plant.db"
TOML

start_background gateway.log timeout 160 "$loopwire" gateway --config "$WORK_DIR/plant.toml"
gateway=$LAST_PID
modbus_port=$(wait_for_log gateway.log 'Modbus TCP on 127\.0\.0\.1 \(listening on port ([0-9]+)\)' 20)
http_port=$(wait_for_log gateway.log 'HTTP API and dashboard on http:..127\.0\.0\.1:([0-9]+)' 20)
wait_for_text "$WORK_DIR/gateway.log" "device oven (tc10@3) answers" 20
wait_for 30 "the oven's DBIRTH" "$python" "$sparkplug_checker" wait "$recording" --timeout 1 --type DBIRTH --edge cabinet1 \
  --device oven

if timeout 120 "$python" "$here/write_audit_check.py" "$loopwire" "$http_port" "$modbus_port" "$MQTT_PORT" "$token_file" \
  "$WORK_DIR/plant.db" "$WORK_DIR/gateway.log" "$recording" "$sparkplug_checker" >"$WORK_DIR/check.out" 2>&1; then
  count_pass
else
  count_failure "one-audit-record-a-write" "$WORK_DIR/check.out"
fi
cat "$WORK_DIR/check.out"

# `loopwire audit` in its other formats and filters, and what it refuses.
db=$WORK_DIR/plant.db
audited() { "$loopwire" audit --database "$db" --from -1h "$@" | tr -d '\r'; }  # the CSV ends its lines with CRLF
expect_equal "$(audited --format csv | head -n 1)" "time,front,peer,user,device,parameter,old_value,new_value,outcome" \
  "the CSV's header"
expect_equal "$(audited --format csv | tail -n +2 | wc -l)" 6 "CSV rows: one a write"
expect_equal "$(audited --device absent --format csv | tail -n +2 | cut -d, -f5 | sort -u)" absent "--device absent"
expect_equal "$(audited --limit 1 --format csv | tail -n +2 | cut -d, -f2)" http "--limit 1: the newest write"
check table-names-the-raw-write 0 "function 6 address 717 count 1" "$loopwire" audit --database "$db"
check refuses-a-time-it-cannot-read 2 'from="yesterday" is not a time' "$loopwire" audit --database "$db" --from yesterday
check refuses-a-file-that-is-not-there 2 "is not a history file" "$loopwire" audit --database "$WORK_DIR/none.db"
check refuses-what-is-no-history-file 2 "cannot be read as an SQLite database" "$loopwire" audit --database "$WORK_DIR/plant.toml"
# Every audit line is at notice level, one a record.
expect_equal "$(grep -c 'audit: ' "$WORK_DIR/gateway.log")" 6 "audit lines in the log"
expect_equal "$(grep 'audit: ' "$WORK_DIR/gateway.log" | grep -vc ' notice ')" 0 "audit lines not at notice level"

# Reloads are audited: a file that does not load (refused, the running configuration kept),
# then one that adds a device (the gateway restarts; its successor records the reload).
# To loopwire itself: timeout(1) would send a signal to its whole process group as well, and
# then ignore the next one.
gateway_process=$(pgrep -P "$gateway")
cp "$WORK_DIR/plant.toml" "$WORK_DIR/plant.good"
printf '[[lines]]\nname = 3\n' >"$WORK_DIR/plant.toml"
kill -HUP "$gateway_process"
wait_for_log gateway.log '(audit: reload SIGHUP: configuration .*plant.toml: none: the file does not load: refused: )' 30 >/dev/null
{
  sed '/^\[modbus_tcp\]/,$d' "$WORK_DIR/plant.good"
  printf '[[lines.devices]]\nname = "dryer"\ndevice = "tc10@5"\npoll = "1s"\n\n'
  sed -n '/^\[modbus_tcp\]/,$p' "$WORK_DIR/plant.good"
} >"$WORK_DIR/plant.toml"
kill -HUP "$gateway_process"
wait_for_log gateway.log '(audit: reload SIGHUP: configuration .*plant.toml: device dryer added to line furnace-line: confirmed)' 30 >/dev/null
# The reloaded gateway's HTTP API (port 0: the kernel's choice again).
new_http_port() { sed -nE 's/.*HTTP API and dashboard on http:..127\.0\.0\.1:([0-9]+).*/\1/p' "$WORK_DIR/gateway.log" | tail -n 1; }
reload_rows() {  # the reload rows of GET /api/audit, oldest first: "peer|device|new_value|outcome"
  curl -fsS "http://127.0.0.1:$(new_http_port)/api/audit?from=-1h" 2>/dev/null |
    $python -c 'import json, sys
for r in reversed(json.load(sys.stdin)["records"]):
    if r["front"] == "reload": print(r["peer"], r["device"], r["new_value"], r["outcome"].split(":")[0], sep="|")' 2>/dev/null
}
two_reloads() { [[ $(reload_rows | wc -l) == 2 ]]; }
wait_for 30 "two reload rows in GET /api/audit" two_reloads
expect_equal "$(reload_rows)" "SIGHUP||none: the file does not load|refused
SIGHUP||device dryer added to line furnace-line|confirmed" "GET /api/audit: the reloads"
expect_equal "$(audited --format csv | tail -n +2 | cut -d, -f2 | sort | uniq -c | tr -s ' ' | tr '\n' ';')" \
  " 3 http; 1 modbus_tcp; 1 mqtt; 2 reload; 1 sparkplug;" "loopwire audit: rows by front after the reloads"
check table-shows-the-reload 0 "device dryer added to line furnace-line" "$loopwire" audit --database "$db"
finish
