#!/usr/bin/env bash
# The gateway's OPC UA front against an independent client (node-opcua, opcua/opcua_check.js):
# a simulated TC10 ("oven") on a pseudo-terminal pair, polled every 300 ms. The client browses
# to every polled parameter and compares value, DataType, EURange and EngineeringUnits with
# GET /api/devices/oven, counts a subscription's notifications, writes in range (the device
# holds it), out of range (Bad_OutOfRange) and to a read-only word (Bad_NotWritable). Then the
# simulator stops: the values go Bad_NoCommunication; it starts again: Good.
set -u
loopwire=${1:?usage: opcua_gateway_test.sh path/to/loopwire}
source "$(dirname "$0")/../support/test_lib.sh"
here=$(cd "$(dirname "$0")" && pwd)
repo=$(cd "$here/../.." && pwd)
skip() { echo "SKIP: $1 (scripts/setup installs it)"; exit 77; }
command -v node >/dev/null || skip "node is not installed (Debian package nodejs)"
command -v socat >/dev/null || skip "socat is not installed (Debian package socat)"
[[ -d $repo/node_modules/node-opcua ]] || skip "node_modules/node-opcua is missing (npm ci)"
"$loopwire" gateway --print-config >/dev/null 2>&1 || fail "loopwire gateway --print-config failed"
export NODE_PATH=$repo/node_modules HOME=$WORK_DIR  # node-opcua keeps its client certificate under HOME
checker=$here/opcua/opcua_check.js

gateway_end=$WORK_DIR/ttyGateway
device_end=$WORK_DIR/ttyDevice
# ignoreeof on the device's end: the pair outlives the simulator, which is stopped and started
# again below (the gateway's port stays open, as a serial line's does when a device goes quiet).
start_background socat.log timeout 170 socat "pty,raw,echo=0,link=$gateway_end" "pty,raw,echo=0,ignoreeof,link=$device_end"
wait_for_path "$gateway_end"
wait_for_path "$device_end"
start_simulator() {
  start_background sim.log timeout 170 "$loopwire" simulate --link "rtu:$device_end?baud=19200&parity=none" --device tc10@3
  simulator=$LAST_PID
}
start_simulator

cat >"$WORK_DIR/plant.toml" <<TOML
[gateway]
name = "plant1"

[[lines]]
name = "furnace-line"
link = "rtu:$gateway_end?baud=19200&parity=none"
timeout = "300ms"

[[lines.devices]]
name = "oven"
device = "tc10@3"
poll = "300ms"

[modbus_tcp]
listen = "127.0.0.1:0"

[http]
listen = "127.0.0.1:0"

[opcua]
listen = "opc.tcp://127.0.0.1:0"
writes = true
TOML

"$loopwire" gateway --config "$WORK_DIR/plant.toml" --check >"$WORK_DIR/check.log" 2>&1 || fail "--check failed: $(cat "$WORK_DIR/check.log")"
expect check-says-opcua grep -q '^OPC UA: opc.tcp://127.0.0.1:0 (urn:loopwire:plant1), anonymous' "$WORK_DIR/check.log"

start_background gateway.log timeout 160 "$loopwire" gateway --config "$WORK_DIR/plant.toml"
opcua_port=$(wait_for_log gateway.log 'OPC UA on opc\.tcp:..127\.0\.0\.1:([0-9]+)' 20)
http_port=$(wait_for_log gateway.log 'HTTP API and dashboard on http:..127\.0\.0\.1:([0-9]+)' 20)
wait_for_text "$WORK_DIR/gateway.log" 'device oven (tc10@3) answers' 20
endpoint=opc.tcp://127.0.0.1:$opcua_port

expect client-check timeout 90 node "$checker" check "$endpoint" "http://127.0.0.1:$http_port" oven
# Every write the client made is audited as the OPC UA front's.
expect audit-confirmed grep -qE 'audit: opcua .*oven\.set_point .*: confirmed' "$WORK_DIR/gateway.log"
expect audit-out-of-range grep -qE 'audit: opcua .*oven\.set_point .*99999 .*refused' "$WORK_DIR/gateway.log"
# /metrics: the writes by outcome (the read-only word is refused by the server itself, unasked),
# and no session left open by the client that closed its own.
metrics=$(curl -s --max-time 10 "http://127.0.0.1:$http_port/metrics")
expect metrics-confirmed grep -qx 'loopwire_opcua_writes_total{gateway="plant1",outcome="confirmed"} 1' <<<"$metrics"
expect metrics-refused grep -qx 'loopwire_opcua_writes_total{gateway="plant1",outcome="refused"} 1' <<<"$metrics"
expect metrics-sessions grep -qE '^loopwire_opcua_sessions\{gateway="plant1"\} [0-9]+$' <<<"$metrics"

# A second gateway on the same endpoint does not start as if it served: it says the port is taken.
cat >"$WORK_DIR/second.toml" <<TOML
[[lines]]
name = "sim"
link = "rtu:virtual?baud=19200"

[[lines.devices]]
name = "other"
device = "tc10@3"

[modbus_tcp]
listen = "127.0.0.1:0"

[opcua]
listen = "opc.tcp://127.0.0.1:$opcua_port"
TOML
timeout 20 "$loopwire" gateway --config "$WORK_DIR/second.toml" >"$WORK_DIR/second.log" 2>&1
second_status=$?
expect second-refused test "$second_status" -ne 0 -a "$second_status" -ne 124
expect second-says-why grep -q "\[opcua\] listen opc.tcp://127.0.0.1:$opcua_port: cannot listen there" "$WORK_DIR/second.log"

kill "$simulator"
expect silent-is-no-communication timeout 60 node "$checker" status "$endpoint" ns=1\;s=oven.measured_value BadNoCommunication 30
start_simulator
expect back-is-good timeout 60 node "$checker" status "$endpoint" ns=1\;s=oven.measured_value Good 30
finish
