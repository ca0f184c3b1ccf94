#!/usr/bin/env bash
# The alarms as a user meets them: a gateway polls a simulated TC10 ("oven") with a high limit
# below its PV. GET /api/alarms shows the alarm active-unacknowledged; an acknowledgement through
# the API makes it active-acknowledged and puts its user and comment in the journal, which
# `loopwire alarms --database` prints; /metrics has its gauge; and once the simulator is killed,
# the device's silent alarm is raised.
set -u
loopwire=${1:?usage: alarms_test.sh path/to/loopwire}
source "$(dirname "$0")/../support/test_lib.sh"
python=/usr/bin/python3

# A pseudo-terminal pair that outlives the simulator: once it is killed the line stays up and
# the device falls silent (a pty of the simulator's own would hang up: the line down instead).
command -v socat >/dev/null || { echo "SKIP: socat is not installed (Debian package socat; scripts/setup installs it)"; exit 77; }
pty="$WORK_DIR/ttyA0"
socat_pair "$pty" "$WORK_DIR/ttyA1"
start_background sim.log "$loopwire" simulate --link "rtu:$WORK_DIR/ttyA1?baud=19200&parity=none" \
  --device tc10@3 --duration 100s
sim_pid=$LAST_PID

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
parameters = ["measured_value", "set_point"]

[modbus_tcp]
enabled = false

[http]
listen = "127.0.0.1:0"
token_file = "$token_file"

[history]
database = "$WORK_DIR/plant.db"

[[alarms.limits]]
device = "oven"
parameter = "PV"
kind = "high"
limit = -150
deadband = 1.0
severity = "high"
message = "oven above -150"
TOML

check configuration-checks 0 "" "$loopwire" gateway --config "$WORK_DIR/plant.toml" --check
start_background gateway.log timeout 90 "$loopwire" gateway --config "$WORK_DIR/plant.toml"
http_port=$(wait_for_log gateway.log 'HTTP API and dashboard on http:..127\.0\.0\.1:([0-9]+)' 20)
api=http://127.0.0.1:$http_port

# state_of ALARM: its state as GET /api/alarms says it.
state_of() {
  curl -s --max-time 5 "$api/api/alarms" |
    "$python" -c 'import json, sys; print(next((a["state"] for a in json.load(sys.stdin)["alarms"] if a["alarm"] == sys.argv[1]), ""))' "$1"
}
state_is() { [[ $(state_of "$1") == "$2" ]]; }

wait_for 20 "oven.measured_value_high active-unacknowledged" state_is oven.measured_value_high active-unacknowledged
alarm=$(curl -s "$api/api/alarms" | "$python" -c '
import json, sys
a = next(a for a in json.load(sys.stdin)["alarms"] if a["alarm"] == "oven.measured_value_high")
print(a["severity"], a["unit"], a["message"], a["value"] is not None, a["since"] is not None)')
expect_equal "$alarm" "high °C oven above -150 True True" "the alarm's severity, unit, message, value and since"
expect_equal "$(state_of oven.silent)" normal "the device answers: not silent"

# Acting needs the token.
check ack-needs-the-token 0 '"error"' curl -s -X POST "$api/api/alarms/oven.measured_value_high/ack"
ack=$(curl -s -o "$WORK_DIR/ack.json" -w '%{http_code}' -X POST -H "Authorization: Bearer $(head -n 1 "$token_file")" \
  -d '{"user": "ann", "comment": "checked on site"}' "$api/api/alarms/oven.measured_value_high/ack")
expect_equal "$ack" 200 "the acknowledgement's status"
expect_equal "$(state_of oven.measured_value_high)" active-acknowledged "after the acknowledgement"
again=$(curl -s -o /dev/null -w '%{http_code}' -X POST -H "Authorization: Bearer $(head -n 1 "$token_file")" \
  "$api/api/alarms/oven.measured_value_high/ack")
expect_equal "$again" 409 "a second acknowledgement: nothing to acknowledge"
expect_equal "$(curl -s -o /dev/null -w '%{http_code}' -X POST -H "Authorization: Bearer $(head -n 1 "$token_file")" \
  "$api/api/alarms/oven.nothing/ack")" 404 "an unknown alarm"

# The journal, through the API and the CLI (committed within a quarter of a second).
journal_has_ack() {
  curl -s --max-time 5 "$api/api/alarms/history?from=-1h" | "$python" -c '
import json, sys
rows = json.load(sys.stdin)["transitions"]
sys.exit(0 if any(r["state"] == "active-acknowledged" and r["user"] == "ann" and r["comment"] == "checked on site" for r in rows) else 1)'
}
wait_for 10 "the acknowledgement in /api/alarms/history" journal_has_ack
check cli-prints-the-ack 0 "checked on site" "$loopwire" alarms --database "$WORK_DIR/plant.db" --from -1h
csv=$("$loopwire" alarms --database "$WORK_DIR/plant.db" --from -1h --format csv | tr -d '\r')
expect_equal "$(echo "$csv" | head -n 1)" "time,alarm,device,parameter,state,value,unit,severity,message,user,comment" "the CSV's header"
expect_equal "$(echo "$csv" | tail -n +2 | cut -d, -f5 | sort | tr '\n' ' ')" "active-acknowledged active-unacknowledged " \
  "the journal's rows: raised, then acknowledged"

expect_equal "$(curl -s "$api/metrics" | grep -F 'loopwire_alarm_active{device="oven",alarm="measured_value_high",severity="high"}' | awk '{print $2}')" \
  1 "the alarm's gauge"
expect_equal "$(curl -s "$api/metrics" | grep -F 'loopwire_alarms{state="active-acknowledged"}' | awk '{print $2}')" 1 \
  "alarms active-acknowledged"

# The simulator goes: the device falls silent.
kill "$sim_pid"
wait_for 20 "oven.silent active-unacknowledged" state_is oven.silent active-unacknowledged
wait_for_text "$WORK_DIR/gateway.log" "alarm oven.silent: active-unacknowledged" 10
expect_equal "$(state_of oven.line_down)" normal "the line is up: one alarm, the device's silence"
# Its limit alarm neither clears nor rises again without a value.
expect_equal "$(state_of oven.measured_value_high)" active-acknowledged "the limit alarm without a value"
finish
