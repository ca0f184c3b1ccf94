#!/usr/bin/env bash
# SIGHUP keeps the HTTP API's clients, against the built gateway: a client
# asking back to back on one keep-alive connection through 10 reloads that reopen the gateway
# ([http] listen unchanged) is answered every time on that connection, by the reloaded gateway
# once it runs (http_reload_check.py).
set -u
loopwire=${1:?usage: http_reload_test.sh path/to/loopwire}
source "$(dirname "$0")/../support/test_lib.sh"

cat >"$WORK_DIR/plant.toml" <<TOML
[[lines]]
name = "furnace"
link = "rtu:virtual?baud=115200&parity=none"

[[lines.devices]]
name = "oven-a"
device = "tc10@3"
poll = "500ms"
parameters = ["measured_value"]

[modbus_tcp]
enabled = false

[http]
listen = "127.0.0.1:0"
TOML
start_background gateway.log "$loopwire" gateway --config "$WORK_DIR/plant.toml"
gateway_pid=$LAST_PID
port=$(wait_for_log gateway.log 'HTTP API and dashboard on http:..127\.0\.0\.1:([0-9]+)' 30)
summary=$(timeout 120 /usr/bin/python3 "$(dirname "$0")/http_reload_check.py" "$port" "$gateway_pid" \
  "$WORK_DIR/plant.toml" "$WORK_DIR/gateway.log" 10 2>&1)
echo "$summary"
expect keep-alive-across-reloads grep -q "across 10 reloads on 1 connection(s)$" <<<"$summary"
expect one-port bash -c "[[ \$(grep -oE 'HTTP API and dashboard on http://127\.0\.0\.1:[0-9]+' '$WORK_DIR/gateway.log' | sort -u | wc -l) -eq 1 ]]"
kill -TERM "$gateway_pid"
wait_for 30 "the gateway to stop on SIGTERM" bash -c "! kill -0 $gateway_pid 2>/dev/null"
finish
