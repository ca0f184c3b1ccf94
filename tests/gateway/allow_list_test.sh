#!/usr/bin/env bash
# Allow lists on the gateway as built, with clients from three loopback addresses (the kernel
# routes all of 127.0.0.0/8 to lo, so a source address picks who the gateway sees):
# - [modbus_tcp] allow: a pymodbus client from 127.0.0.2, outside the list, is closed at accept
#   and counted in /metrics; clients from 127.0.0.1 and 127.0.0.3 are served;
# - [modbus_tcp] write_allow: 127.0.0.3 reads, but its write is answered with exception 01h
#   and logged, and the set point keeps 127.0.0.1's value;
# - [http] allow: curl from 127.0.0.2 gets no response, from 127.0.0.1 the API; counted;
# - a reload that narrows [http] allow closes the kept-alive connection of an address it leaves
#   out (127.0.0.4), counted, while the others are served;
# - a list entry that is not an address or a network is refused by --check with its place.
set -u
loopwire=${1:?usage: allow_list_test.sh path/to/loopwire}
source "$(dirname "$0")/../support/test_lib.sh"
python=/usr/bin/python3
client="$(dirname "$0")/allow_list_client.py"

write_config() {  # FILE [MODBUS TCP LINES] [HTTP LINES] : one simulated TC10 (unit 3) on a virtual line
  cat >"$1" <<TOML
[[lines]]
name = "furnace"
link = "rtu:virtual?baud=19200&parity=none"

[[lines.devices]]
name = "oven"
device = "tc10@3"
poll = "1s"

[modbus_tcp]
listen = "127.0.0.1:0"
${2:-}

[http]
listen = "127.0.0.1:0"
${3:-}

[log]
level = "debug"
statistics = "off"
TOML
}

# ---- --check names a bad entry -----------------------------------------------------------------
write_config "$WORK_DIR/bad.toml" 'allow = ["127.0.0.1", "10.1.0.0/33"]'
check check-refuses-bad-network 2 '"10.1.0.0/33" is not an address or a network' \
  "$loopwire" gateway --config "$WORK_DIR/bad.toml" --check
check check-names-the-entry 2 'modbus_tcp.allow[1]' "$loopwire" gateway --config "$WORK_DIR/bad.toml" --check
write_config "$WORK_DIR/bad-http.toml" '' 'allow = "127.0.0.1"'
check check-wants-a-list 2 'http.allow: expected a list of addresses and networks' \
  "$loopwire" gateway --config "$WORK_DIR/bad-http.toml" --check

# ---- the lists at work -------------------------------------------------------------------------
write_config "$WORK_DIR/plant.toml" 'allow = ["127.0.0.1", "127.0.0.3/32", "::1"]
write_allow = ["127.0.0.1"]' 'allow = ["127.0.0.0/31", "127.0.0.4"]'
check check-accepts-lists 0 "" "$loopwire" gateway --config "$WORK_DIR/plant.toml" --check
start_tcp_server gateway.log timeout 120 "$loopwire" gateway --config "$WORK_DIR/plant.toml"
LAST_GATEWAY_PID=$LAST_PID
modbus_port=$PORT
http_port=$(wait_for_log gateway.log 'HTTP API and dashboard on http:..127\.0\.0\.1:([0-9]+)')

check allowed-writer-writes 0 "written" "$python" "$client" 127.0.0.1 "$modbus_port" write 321
check refused-address-gets-no-connection 0 "no connection" "$python" "$client" 127.0.0.2 "$modbus_port" read
check read-only-address-reads 0 "value 321" "$python" "$client" 127.0.0.3 "$modbus_port" read
check read-only-address-cannot-write 0 "exception 1" "$python" "$client" 127.0.0.3 "$modbus_port" write 999
check value-kept 0 "value 321" "$python" "$client" 127.0.0.1 "$modbus_port" read
expect write-refusal-logged grep -q "the client's address is not in modbus_tcp.write_allow" "$WORK_DIR/gateway.log"
expect refusal-logged grep -q "Modbus TCP: refused a client from 127.0.0.2:[0-9]*: its address is not in the allow list" \
  "$WORK_DIR/gateway.log"

status=0
curl -s --max-time 5 --interface 127.0.0.2 "http://127.0.0.1:$http_port/api/devices" >"$WORK_DIR/outside.txt" || status=$?
if [[ $status -ne 0 && ! -s $WORK_DIR/outside.txt ]]; then count_pass
else count_failure "http-outside-gets-nothing (curl status $status)" "$WORK_DIR/outside.txt"; fi
check http-inside-served 0 '"oven"' curl -s --max-time 10 "http://127.0.0.1:$http_port/api/devices"

# A keep-alive connection from 127.0.0.4, answered once (a short 404); then a reload leaves 127.0.0.4 out.
keep_alive() {  # asks twice on one connection from 127.0.0.4, the second time once $WORK_DIR/go exists
  /usr/bin/python3 - "$http_port" "$WORK_DIR/go" <<'PY'
import os, socket, sys, time
port, go = int(sys.argv[1]), sys.argv[2]
ask = b"GET /api/no-such-thing HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n"
s = socket.create_connection(("127.0.0.1", port), timeout=10, source_address=("127.0.0.4", 0))
s.sendall(ask)
print("first:", s.recv(65536).split(b"\r\n", 1)[0].decode(), flush=True)
deadline = time.monotonic() + 30
while not os.path.exists(go) and time.monotonic() < deadline:
    time.sleep(0.02)
try:
    s.sendall(ask)
    answer = s.recv(65536)
    print("second:", answer.split(b"\r\n", 1)[0].decode() if answer else "closed", flush=True)
except OSError as error:
    print("second: closed", error, flush=True)
PY
}
start_background keep_alive.log keep_alive
wait_for_text "$WORK_DIR/keep_alive.log" "first: HTTP/1.1 404"
write_config "$WORK_DIR/plant.toml" 'allow = ["127.0.0.1", "127.0.0.3/32", "::1"]
write_allow = ["127.0.0.1"]' 'allow = ["127.0.0.0/31"]'
kill -HUP "$LAST_GATEWAY_PID"
wait_for_log gateway.log 'configuration .* (reloaded)' 30 >/dev/null
touch "$WORK_DIR/go"
wait_for_text "$WORK_DIR/keep_alive.log" "second:" 30
expect keep-alive-outside-closed-on-reload grep -q "second: closed" "$WORK_DIR/keep_alive.log"
check http-inside-served-after-reload 0 '"oven"' curl -s --max-time 10 "http://127.0.0.1:$http_port/api/devices"

modbus_refused=$(metric "$http_port" modbus_tcp_connections_not_allowed_total)
http_refused=$(metric "$http_port" http_connections_not_allowed_total)
echo "refused at accept: Modbus TCP ${modbus_refused:-?}, HTTP ${http_refused:-?}"
expect_equal "${modbus_refused:-}" 1 "Modbus TCP clients refused by the allow list"
expect_equal "${http_refused:-}" 2 "HTTP clients refused by the allow list (one at accept, one at the reload)"
finish
