#!/usr/bin/env bash
# The gateway as built, against clients that try to exhaust it, on a simulated line:
# - under `ulimit -n 1024`, 1100 idle connections to the Modbus TCP front: a pymodbus client
#   still reads the value it wrote and the HTTP front still answers (the front holds at most
#   [modbus_tcp] max_connections, closing the idlest for each newcomer);
# - a connect-send-close storm, after which the honest client still reads the right value, not
#   exception 0Bh (requests of connections that have gone never take the line);
# - a FIFO named as password_file or ca_file is refused by --check at once; SIGHUP with a FIFO
#   in the configuration is refused and SIGTERM still stops the gateway;
# - SIGHUP with the file unchanged, or only its log level changed, keeps a client's connection,
#   and so does one that reopens the gateway with [modbus_tcp] unchanged;
# - the gateway raises its soft descriptor limit to the hard one at start.
set -u
loopwire=${1:?usage: front_bounds_test.sh path/to/loopwire}
source "$(dirname "$0")/../support/test_lib.sh"
python=/usr/bin/python3
flood="$(dirname "$0")/front_flood.py"

write_config() {  # FILE [EXTRA TOML] : one simulated TC10 (unit 3) on a 9600-baud virtual line
  cat >"$1" <<TOML
[[lines]]
name = "furnace"
link = "rtu:virtual?baud=9600&parity=none"
timeout = "300ms"

[[lines.devices]]
name = "oven"
device = "tc10@3"
poll = "1s"

[modbus_tcp]
listen = "127.0.0.1:0"

[http]
listen = "127.0.0.1:0"

[log]
level = "debug"
statistics = "off"
${2:-}
TOML
}

# The PID of the gateway a `timeout` started as LAST_PID runs.
gateway_pid() {
  local child
  wait_for 10 "the gateway under timeout" bash -c "pgrep -P $1 >/dev/null"
  child=$(pgrep -P "$1" | head -n 1)
  echo "$child"
}


# ---- FIFOs where files are expected: refused by --check at once, never opened ------------------
mkfifo "$WORK_DIR/password.fifo" "$WORK_DIR/ca.fifo"
write_config "$WORK_DIR/fifo-password.toml" '
[mqtt]
broker = "mqtt://127.0.0.1:1883"
username = "gateway"
password_file = "password.fifo"'
check check-refuses-fifo-password-file 2 'mqtt.password_file: "'"$WORK_DIR"'/password.fifo" is a FIFO (named pipe), not a regular file' \
  "$loopwire" gateway --config "$WORK_DIR/fifo-password.toml" --check
write_config "$WORK_DIR/fifo-ca.toml" '
[mqtt]
broker = "mqtts://127.0.0.1:8883"
ca_file = "ca.fifo"'
check check-refuses-fifo-ca-file 2 "mqtt.ca_file: " "$loopwire" gateway --config "$WORK_DIR/fifo-ca.toml" --check
check check-says-what-to-do 2 "name a regular file" "$loopwire" gateway --config "$WORK_DIR/fifo-ca.toml" --check

# ---- 1100 idle connections under `ulimit -n 1024` ----------------------------------------------
write_config "$WORK_DIR/plant.toml"
start_tcp_server gateway.log timeout 200 bash -c 'ulimit -n 1024; exec "$0" gateway --config "$1"' \
  "$loopwire" "$WORK_DIR/plant.toml"
modbus_port=$PORT
flooded=$(gateway_pid "$LAST_PID")
http_port=$(wait_for_log gateway.log 'HTTP API and dashboard on http:..127\.0\.0\.1:([0-9]+)')  # no slashes: sed s///
check honest-client-writes 0 "written" "$python" "$flood" write "$modbus_port" 3 717 123  # TC10 SP at 717

touch "$WORK_DIR/hold"
start_background idle.log "$python" "$flood" idle "$modbus_port" 1100 "$WORK_DIR/hold"
idle_pid=$LAST_PID
wait_for_text "$WORK_DIR/idle.log" "opened 1100" 60
check read-with-1100-idle-connections 0 "value 123" "$python" "$flood" read "$modbus_port" 3 717
check http-with-1100-idle-connections 0 "200" curl -s -o /dev/null -w '%{http_code}' --max-time 10 \
  "http://127.0.0.1:$http_port/api/devices"
evicted=$(metric "$http_port" modbus_tcp_connections_evicted_total)
open=$(metric "$http_port" modbus_tcp_connections_open)
echo "after 1100 idle connections: ${evicted:-?} evicted, ${open:-?} open"
if [[ ${evicted:-0} -ge 1000 && ${open:-999} -le 64 ]]; then count_pass
else echo "FAIL idle-connections-evicted: evicted '${evicted:-}', open '${open:-}'"; failures=$((failures + 1)); fi
expect eviction-logged-at-debug grep -q "debug loopwire: gateway: Modbus TCP: 64 connections open (the most allowed): closed the one from" \
  "$WORK_DIR/gateway.log"
rm -f "$WORK_DIR/hold"
wait "$idle_pid"

# ---- a connect-send-close storm ------------------------------------------------------------------
storm_out=$("$python" "$flood" storm "$modbus_port" 2000 3 717 2>&1)
echo "$storm_out"
check read-after-the-storm 0 "value 123" "$python" "$flood" read "$modbus_port" 3 717
sent=$(metric "$http_port" line_requests_total)
abandoned=$(metric "$http_port" line_abandoned_total)
echo "after the storm: the line sent ${sent:-?} requests in all (polls included), ${abandoned:-?} abandoned unsent"

kill -TERM "$flooded"
wait_for 30 "the flooded gateway to stop on SIGTERM" bash -c "! kill -0 $flooded 2>/dev/null"
expect front-summary-at-exit grep -q "Modbus TCP front: [0-9]* connection(s) accepted" "$WORK_DIR/gateway.log"

# ---- SIGHUP with FIFOs in the configuration, then SIGTERM --------------------------------------
write_config "$WORK_DIR/reload.toml"
start_tcp_server reload.log timeout 200 bash -c 'ulimit -Sn 256; exec "$0" gateway --config "$1"' \
  "$loopwire" "$WORK_DIR/reload.toml"
reloading=$(gateway_pid "$LAST_PID")
expect descriptor-limit-raised grep -q "open files: limit raised from 256 to the hard limit" "$WORK_DIR/reload.log"
write_config "$WORK_DIR/reload.toml" '
[mqtt]
broker = "mqtt://127.0.0.1:1883"
username = "gateway"
password_file = "password.fifo"'
kill -HUP "$reloading"
wait_for_text "$WORK_DIR/reload.log" "configuration not reloaded, the running one is kept" 30
expect reload-names-the-fifo grep -q 'mqtt.password_file: .*is a FIFO (named pipe)' "$WORK_DIR/reload.log"
rm -f "$WORK_DIR/reload.toml"
mkfifo "$WORK_DIR/reload.toml"  # the configuration itself
kill -HUP "$reloading"
wait_for 30 "the second reload to be refused" bash -c "[[ \$(grep -c 'configuration not reloaded' '$WORK_DIR/reload.log') -ge 2 ]]"
check still-serving-after-refused-reloads 0 "value" "$python" "$flood" read "$PORT" 3 717

# ---- SIGHUP with nothing changed, then with only the log level changed: a connection stays up -
rm -f "$WORK_DIR/reload.toml"
write_config "$WORK_DIR/reload.toml"  # what the gateway runs
touch "$WORK_DIR/hold"
"$python" "$flood" hold-read "$PORT" 3 717 "$WORK_DIR/hold" >"$WORK_DIR/held.out" 2>&1 &
held=$!
wait_for 30 "the held connection's first read" grep -q "^value" "$WORK_DIR/held.out"
kill -HUP "$reloading"
wait_for 30 "the unchanged reload" grep -q "reload.toml re-read: nothing changed; lines, listeners, connections and MQTT stay up" "$WORK_DIR/reload.log"
sed -i 's/level = "debug"/level = "info"/' "$WORK_DIR/reload.toml"
kill -HUP "$reloading"
wait_for 30 "the log-level reload" grep -q "reload.toml re-read: only the log level changed" "$WORK_DIR/reload.log"
expect no-restart-on-unchanged-reload bash -c "! grep -q 'configuration .*reload.toml reloaded' '$WORK_DIR/reload.log'"
# A change that reopens the gateway (the poll interval) with [modbus_tcp] as it was: the front,
# and the held connection with it, stays; the reopened gateway answers on that connection.
sed -i 's/poll = "1s"/poll = "2s"/' "$WORK_DIR/reload.toml"
kill -HUP "$reloading"
wait_for 30 "the reload that reopens the gateway" grep -q "configuration .*reload.toml reloaded" "$WORK_DIR/reload.log"
wait_for 30 "the front kept" grep -q "Modbus TCP front kept on port $PORT: 1 client connection(s) stay up" "$WORK_DIR/reload.log"
wait_for 30 "the reopened gateway" bash -c "(( \$(grep -c 'line(s), 1 device(s); Modbus TCP on' '$WORK_DIR/reload.log') >= 2 ))"
rm -f "$WORK_DIR/hold"
wait "$held"
expect held-connection-survives-reloads grep -q "on the same connection" "$WORK_DIR/held.out"
kill -TERM "$reloading"
wait_for 30 "the gateway to stop on SIGTERM after refused reloads" bash -c "! kill -0 $reloading 2>/dev/null"
expect stopped-cleanly grep -q "line furnace" "$WORK_DIR/reload.log"

finish
