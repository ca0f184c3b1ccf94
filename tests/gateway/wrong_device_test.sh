#!/usr/bin/env bash
# The right device or none. An AC20 answers at unit 1 where the configuration names a TC10
# (`device = "tc10@1"`): its identification word reads what no TC10's does, so the device is
# `wrong-device` with the reason on every front (the HTTP API, MQTT's status topic, which Home
# Assistant's availability reads, no Sparkplug birth) and in `loopwire monitor`'s records, and
# none of its words is shown as a value. A second gateway behind the first's Modbus TCP front
# gets exception 0Bh for a unit the first cannot reach: that device is `no-reply`, not partial.
set -u
loopwire=${1:?usage: wrong_device_test.sh path/to/loopwire}
source "$(dirname "$0")/../support/test_lib.sh"
python=/usr/bin/python3
[[ -x /usr/sbin/mosquitto ]] || skip "/usr/sbin/mosquitto is not installed (Debian package mosquitto)"
command -v mosquitto_sub >/dev/null || skip "mosquitto_sub is not installed (Debian package mosquitto-clients)"
command -v curl >/dev/null || skip "curl is not installed"

pty="$WORK_DIR/ttyW0"
start_background sim.log "$loopwire" simulate --link "rtu:/unused?baud=19200&parity=none" --pty "$pty" \
  --device ac20@1 --device tc10@3 --duration 200s
wait_for_path "$pty"

# The monitor alone on the line first: its JSON-lines records say wrong-device for the AC20
# asked for as a TC10, with no values, and read the real TC10.
timeout 60 "$loopwire" monitor --link "rtu:$pty?baud=19200&parity=none" --timeout 300ms --device tc10@1 --device tc10@3 \
  --count 2 --interval 300ms --format jsonl >"$WORK_DIR/monitor.jsonl" 2>"$WORK_DIR/monitor.err"
expect monitor-runs test -s "$WORK_DIR/monitor.jsonl"
expect monitor-says-wrong-device $python - "$WORK_DIR/monitor.jsonl" <<'PY'
import json, sys
records = [json.loads(line) for line in open(sys.argv[1])]
last = records[-1]["devices"]
wrong, right = last["tc10@1"], last["tc10@3"]
assert wrong["status"] == "wrong-device", wrong
assert "instrument" in wrong["error"] or "word" in wrong["error"], wrong["error"]
assert all(v["value"] is None for r in records for v in r["devices"]["tc10@1"]["values"].values()), records
assert right["status"] == "ok", right
PY
timeout 60 "$loopwire" monitor --link "rtu:$pty?baud=19200&parity=none" --timeout 300ms --device tc10@1 --no-identify \
  --count 1 --format jsonl >"$WORK_DIR/trusting.jsonl" 2>&1
expect monitor-no-identify-takes-it grep -q '"status":"ok"' "$WORK_DIR/trusting.jsonl"

# The broker logs subscriptions, so the test waits for its observer to be in place, not for time.
start_mosquitto 150 "log_dest stderr" "log_type information" "log_type subscribe"
cat >"$WORK_DIR/plant.toml" <<TOML
[gateway]
name = "plant1"

[[lines]]
name = "furnace-line"
link = "rtu:$pty?baud=19200&parity=none"
timeout = "300ms"

[[lines.devices]]
name = "furnace"
device = "tc10@1"
poll = "1s"

[[lines.devices]]
name = "oven"
device = "tc10@3"
poll = "1s"

[[lines.devices]]
name = "absent"
device = "tc10@4"
poll = "5s"

[modbus_tcp]
listen = "127.0.0.1:0"

[http]
listen = "127.0.0.1:0"

[mqtt]
broker = "mqtt://127.0.0.1:$MQTT_PORT"
discovery = "homeassistant"

[sparkplug]
broker = "mqtt://127.0.0.1:$MQTT_PORT"
group_id = "plant"
TOML
# Births are not retained: the observer is in place before the gateway starts.
start_background births.log timeout 60 mosquitto_sub -h 127.0.0.1 -p "$MQTT_PORT" -v -W 40 -t 'spBv1.0/plant/DBIRTH/#'
wait_for_text "$WORK_DIR/broker.log" " spBv1.0/plant/DBIRTH/#"
start_tcp_server gateway.log timeout 120 "$loopwire" gateway --config "$WORK_DIR/plant.toml"
gateway_port=$PORT
http=$(wait_for_log gateway.log 'HTTP API and dashboard on http:..127\.0\.0\.1:([0-9]+)' 30)

wait_for_text "$WORK_DIR/gateway.log" "the unit is not tc10@1" 30
# At warning, which `journalctl -p warning` and `level = "warning"` keep.
expect log-says-why grep -qE 'Z warning loopwire: gateway: device furnace \(tc10@1\): the unit is not tc10@1: its .* reads' "$WORK_DIR/gateway.log"
api() { curl -sf "http://127.0.0.1:$http/api/devices/$1"; }
wait_for 20 "oven ok on the API" bash -c "curl -sf 'http://127.0.0.1:$http/api/devices/oven' | grep -q '\"status\":\"ok\"'"
api furnace >"$WORK_DIR/furnace.json"
if $python - "$WORK_DIR/furnace.json" <<'PY'; then count_pass; else count_failure api-wrong-device; fi
import json, sys
device = json.load(open(sys.argv[1]))
assert device["status"] == "wrong-device", device
assert "the unit is not tc10@1" in device.get("error", ""), device
polled = [p for p in device["parameters"] if p["polled"]]
# A value's own words are DESIGN's (error); the device's status and every value's error say why.
assert polled and all(p["value"] is None and p["status"] == "error" and "the unit is not tc10@1" in p["error"]
                      for p in polled), [(p["name"], p["status"], p["error"]) for p in polled]
PY
expect mqtt-status-wrong-device bash -c "[[ \$(mosquitto_sub -h 127.0.0.1 -p $MQTT_PORT -C 1 -W 10 -t loopwire/plant1/furnace/status) == wrong-device ]]"
expect mqtt-oven-ok bash -c "[[ \$(mosquitto_sub -h 127.0.0.1 -p $MQTT_PORT -C 1 -W 10 -t loopwire/plant1/oven/status) == ok ]]"
# Home Assistant's availability: the wrong device is unavailable, the right one available.
expect ha-unavailable bash -c "[[ \$(mosquitto_sub -h 127.0.0.1 -p $MQTT_PORT -C 1 -W 10 -t loopwire/plant1/furnace/availability) == offline ]]"
expect ha-available bash -c "[[ \$(mosquitto_sub -h 127.0.0.1 -p $MQTT_PORT -C 1 -W 10 -t loopwire/plant1/oven/availability) == online ]]"
expect mqtt-no-garbage-value bash -c "! mosquitto_sub -h 127.0.0.1 -p $MQTT_PORT -C 1 -W 3 -t loopwire/plant1/furnace/measured_value | grep -qE '^-?[0-9]'"
wait_for 30 "the oven's Sparkplug birth" grep -q 'spBv1.0/plant/DBIRTH/plant1/oven' "$WORK_DIR/births.log"
expect sparkplug-no-birth-for-wrong-device bash -c "! grep -q 'DBIRTH/plant1/furnace' '$WORK_DIR/births.log'"

# A gateway behind this one's Modbus TCP front: unit 4 is configured there and silent, so the
# front answers 0Bh (gateway target failed to respond), which is no reply from the device.
cat >"$WORK_DIR/behind.toml" <<TOML
[[lines]]
name = "upstream"
link = "tcp://127.0.0.1:$gateway_port"
timeout = "2s"

[[lines.devices]]
name = "beyond"
device = "tc10@4"
poll = "2s"
identify = false

[[lines.devices]]
name = "oven-beyond"
device = "tc10@3"
poll = "2s"

[modbus_tcp]
enabled = false

[http]
listen = "127.0.0.1:0"
TOML
start_background behind.log timeout 60 "$loopwire" gateway --config "$WORK_DIR/behind.toml"
behind=$(wait_for_log behind.log 'HTTP API and dashboard on http:..127\.0\.0\.1:([0-9]+)' 30)
status_of() { curl -sf "http://127.0.0.1:$1/api/devices/$2" | "$python" -c 'import json,sys; print(json.load(sys.stdin)["status"])'; }
export python; export -f status_of
wait_for 30 "oven-beyond ok behind the gateway" bash -c "[[ \$(status_of $behind oven-beyond) == ok ]] || { curl -s 'http://127.0.0.1:$behind/api/devices/oven-beyond' >'$WORK_DIR/oven-beyond.log'; false; }"
wait_for 30 "beyond no-reply behind the gateway" bash -c "curl -sf 'http://127.0.0.1:$behind/api/devices/beyond' | grep -q '\"status\":\"no-reply\"'"
expect 0Bh-is-no-reply bash -c "curl -sf 'http://127.0.0.1:$behind/api/devices/beyond' | grep -q 'gateway target device failed to respond'"
finish
