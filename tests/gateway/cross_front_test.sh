#!/usr/bin/env bash
# One truth on every front: a gateway polls a simulated TC10 and AC20 with their
# default watch lists and serves them over Modbus TCP, HTTP, MQTT with Home Assistant
# discovery and Sparkplug B, and keeps their history; cross_front_check.py reads every polled
# value through the HTTP API, MQTT and its /meta, the discovery documents, /metrics,
# `loopwire read --json`, `loopwire monitor --format csv`, the public library, the Sparkplug
# births and data, and the history file's last rows, and wants the same text, unit, numeric
# limits and status from all.
# Then the TC10's unit word is changed (°C to °F), and the word bounding its set point, through
# the HTTP API, and every front must follow.
set -u
loopwire=${1:?usage: cross_front_test.sh path/to/loopwire path/to/api_read_by_name}
read_by_name=${2:?usage: cross_front_test.sh path/to/loopwire path/to/api_read_by_name}
source "$(dirname "$0")/../support/test_lib.sh"
python=/usr/bin/python3
broker_program=/usr/sbin/mosquitto
skip() { echo "SKIP: $1 (scripts/setup installs it)"; exit 77; }
[[ -x $broker_program ]] || skip "$broker_program is not installed (Debian package mosquitto)"
$python -c 'import paho.mqtt' 2>/dev/null || skip "paho.mqtt is not importable by $python (Debian package python3-paho-mqtt)"
command -v protoc >/dev/null || skip "protoc is not installed (Debian package protobuf-compiler): the Sparkplug observer needs it"
$python -c 'import google.protobuf' 2>/dev/null || skip "google.protobuf is not importable by $python (Debian package python3-protobuf)"

# The Sparkplug observer's own protobuf module, from the repository's .proto.
repo=$(cd "$(dirname "$0")/../.." && pwd)
protoc --python_out="$WORK_DIR" -I "$repo/src/gateway/sparkplug" "$repo/src/gateway/sparkplug/sparkplug_b.proto" ||
  fail "protoc could not compile src/gateway/sparkplug/sparkplug_b.proto"
export SPARKPLUG_PB_DIR=$WORK_DIR

start_mosquitto 200
mqtt_port=$MQTT_PORT

token_file=$WORK_DIR/token
head -c 24 /dev/urandom | base64 >"$token_file"
chmod 600 "$token_file"
# No parameters lists: the profiles' default watch lists (PV, SP, OUT, status words, mode).
cat >"$WORK_DIR/plant.toml" <<TOML
[gateway]
name = "plant1"

[[lines]]
name = "sim"
link = "rtu:virtual?baud=19200"

[[lines.devices]]
name = "oven"
device = "tc10@3"
poll = "300ms"

[[lines.devices]]
name = "furnace"
device = "ac20@1"
poll = "300ms"

[modbus_tcp]
listen = "127.0.0.1:0"

[http]
listen = "127.0.0.1:0"
token_file = "$token_file"

[mqtt]
broker = "mqtt://127.0.0.1:$mqtt_port"
writes = true
discovery = "homeassistant"

[sparkplug]
broker = "mqtt://127.0.0.1:$mqtt_port"
group_id = "plant"

[history]
database = "$WORK_DIR/plant.db"
TOML

start_background gateway.log timeout 200 "$loopwire" gateway --config "$WORK_DIR/plant.toml"
modbus_port=$(wait_for_log gateway.log 'Modbus TCP on 127\.0\.0\.1 \(listening on port ([0-9]+)\)' 20)
http_port=$(wait_for_log gateway.log 'HTTP API and dashboard on http:..127\.0\.0\.1:([0-9]+)' 20)
wait_for_text "$WORK_DIR/gateway.log" "device oven (tc10@3) answers"
wait_for_text "$WORK_DIR/gateway.log" "device furnace (ac20@1) answers"

checker=("$python" "$(dirname "$0")/cross_front_check.py" "$loopwire" "$read_by_name" "$modbus_port" "$http_port" "$mqtt_port"
         "$token_file" --history "$WORK_DIR/plant.db")
# run_checker NAME ARGS... : one run of the checker (up to 20 rounds of every front), its report shown.
run_checker() {
    local name=$1
    shift
    if timeout 150 "${checker[@]}" "$@" >"$WORK_DIR/$name.out" 2>&1; then count_pass; else count_failure "$name" "$WORK_DIR/$name.out"; fi
    cat "$WORK_DIR/$name.out"
}
run_checker every-front-agrees --expect-unit measured_value=°C
run_checker every-front-follows-the-unit-word --write oven temperature_unit=F --expect-unit measured_value=°F \
  --expect-unit set_point=°F
# A write of the word that bounds the set point (SP.HL, not polled itself): every front's limit
# follows at the next poll, not at the bounds' 5-minute refresh.
run_checker every-front-follows-a-new-limit --write oven set_point_high_limit=650 --expect-max set_point=650
# The same word written by a Modbus TCP client through the front: raw registers to the gateway,
# which has the device's next poll read its bounds again all the same.
run_checker every-front-follows-a-limit-a-modbus-client-wrote --write-modbus oven set_point_high_limit=620 \
  --expect-max set_point=620
finish
