#!/usr/bin/env bash
# Lines come back by themselves (gateway/reopening_master.hpp). A gateway with three lines:
#   furnace-line, a pseudo-terminal served by `loopwire simulate`, whose simulator is killed
#     (SIGKILL: what pulling a USB-RS485 adapter looks like to the gateway) and started again on
#     the same path;
#   later-line, whose port does not exist when the gateway starts and appears afterwards;
#   virtual-line, simulated inside the gateway.
# The gateway starts although later-line's port is missing, serves virtual-line's device,
# reports the missing and the killed lines as down (log, /api/devices, 0Ah to Modbus TCP
# clients), and each line comes up again by itself once its port is back. A reload that leaves
# two of the lines alone keeps them open. The gateway logs as under systemd with stderr to the
# journal (JOURNAL_STREAM names its stderr): a line down is a warning, its coming up a notice.
set -u
loopwire=${1:?usage: line_recovery_test.sh path/to/loopwire}
source "$(dirname "$0")/../support/test_lib.sh"

furnace_pty="$WORK_DIR/ttyFurnace"
later_pty="$WORK_DIR/ttyLater"

start_furnace_simulator() {  # LOG
  start_background "$1" "$loopwire" simulate --link "rtu:/unused?baud=19200&parity=none" --pty "$furnace_pty" \
    --device tc10@3 --duration 100s  # the whole test (ctest: 120 s)
  furnace_sim=$LAST_PID
}
start_furnace_simulator sim1.log
wait_for_path "$furnace_pty"

cat >"$WORK_DIR/plant.toml" <<TOML
[[lines]]
name = "furnace-line"
link = "rtu:$furnace_pty?baud=19200&parity=none"
timeout = "300ms"

[[lines.devices]]
name = "oven1"
device = "tc10@3"
poll = "500ms"

[[lines]]
name = "later-line"
link = "rtu:$later_pty?baud=19200&parity=none"
timeout = "300ms"

[[lines.devices]]
name = "kiln"
device = "rampsoak@5"
poll = "500ms"

[[lines]]
name = "virtual-line"
link = "rtu:virtual?baud=19200&parity=none"

[[lines.devices]]
name = "furnace"
device = "ac20@1"
poll = "500ms"

[modbus_tcp]
listen = "127.0.0.1:0"

[http]
listen = "127.0.0.1:0"

[log]
statistics = "off"
TOML

# --check: a port missing now is a warning, not an error.
check check-warns-of-the-missing-port 0 "warning: port $later_pty does not exist now" \
  "$loopwire" gateway --config "$WORK_DIR/plant.toml" --check
# A port that is there but is no serial port would never open: refused, at --check as at start.
mkdir "$WORK_DIR/not-a-port"
mkfifo "$WORK_DIR/fifo-port"
sed "s|rtu:$later_pty?|rtu:$WORK_DIR/not-a-port?|" "$WORK_DIR/plant.toml" >"$WORK_DIR/dir-port.toml"
sed "s|rtu:$later_pty?|rtu:$WORK_DIR/fifo-port?|" "$WORK_DIR/plant.toml" >"$WORK_DIR/fifo-port.toml"
check check-refuses-a-directory-as-port 2 "line later-line: $WORK_DIR/not-a-port is a directory, not a serial port" \
  "$loopwire" gateway --config "$WORK_DIR/dir-port.toml" --check
check start-refuses-a-fifo-as-port 2 "line later-line: $WORK_DIR/fifo-port is a FIFO (named pipe), not a serial port" \
  "$loopwire" gateway --config "$WORK_DIR/fifo-port.toml"
# A character device that is no terminal would never be one either.
sed "s|rtu:$later_pty?|rtu:/dev/zero?|" "$WORK_DIR/plant.toml" >"$WORK_DIR/zero-port.toml"
check check-refuses-dev-zero-as-port 2 "line later-line: /dev/zero is a character device of the kernel's \"mem\" class" \
  "$loopwire" gateway --config "$WORK_DIR/zero-port.toml" --check

# The device and inode of the gateway's stderr, as systemd gives them for the journal's stream.
: >"$WORK_DIR/gateway.log"
journal_stream=$(stat -c '%d:%i' "$WORK_DIR/gateway.log")
start_tcp_server gateway.log env JOURNAL_STREAM="$journal_stream" timeout 100 "$loopwire" gateway --config "$WORK_DIR/plant.toml"
gateway_pid=$(pgrep -P "$LAST_PID")  # the gateway itself, not `timeout` around it
modbus="tcp://127.0.0.1:$PORT"
http=$(wait_for_log gateway.log 'HTTP API and dashboard on http:..127\.0\.0\.1:([0-9]+)' 20)
api="http://127.0.0.1:$http/api/devices"

device_status() {  # NAME : the device's status in the HTTP API
  curl -sf "$api/$1" | /usr/bin/python3 -c 'import json, sys; print(json.load(sys.stdin)["status"])'
}
status_is() {  # NAME STATUS
  [[ $(device_status "$1") == "$2" ]]
}

# Started with later-line down: logged once, its device line-down, the others served.
wait_for_log gateway.log "line later-line \(rtu:[^)]*\) is (down): " 20 >/dev/null
wait_for 30 "furnace (virtual-line) ok" status_is furnace ok
wait_for 30 "oven1 (furnace-line) ok" status_is oven1 ok
wait_for 30 "kiln (later-line) line-down" status_is kiln line-down
expect kiln-says-why bash -c "curl -sf '$api/kiln' | grep -q 'no such port $later_pty'"
check down-line-gets-0Ah 5 "exception 10" "$loopwire" read --link "$modbus" --unit 5 holding 0

# The missing port appears: later-line comes up and its device is served.
start_background sim3.log "$loopwire" simulate --link "rtu:/unused?baud=19200&parity=none" --pty "$later_pty" \
  --device rampsoak@5 --duration 100s
wait_for_path "$later_pty"
wait_for 45 "kiln ok once its port appeared" status_is kiln ok
wait_for_log gateway.log "line later-line \(rtu:[^)]*\) is (up) again after" 10 >/dev/null

# The furnace line's simulator dies: the line goes down, its device says so, clients get 0Ah.
# Its link goes too, as a USB adapter's device node does when it is pulled out (a dangling link
# could meet another program's pseudo-terminal once the kernel hands out the number again).
kill -KILL "$furnace_sim"
rm -f "$furnace_pty"
wait_for 30 "oven1 line-down after the simulator died" status_is oven1 line-down
wait_for_log gateway.log "line furnace-line \(rtu:[^)]*\) is (down): " 10 >/dev/null
check killed-line-gets-0Ah 5 "exception 10" "$loopwire" read --link "$modbus" --unit 3 holding 0
expect virtual-line-unaffected status_is furnace ok

# Started again on the same path: the line reopens by itself within one back-off (at most 30 s
# after the simulator is back; generous for a loaded machine) and the device is ok again.
start_furnace_simulator sim2.log
wait_for 45 "oven1 ok again after the simulator came back" status_is oven1 ok
wait_for_log gateway.log "line furnace-line \(rtu:[^)]*\) is (up) again after" 10 >/dev/null
check read-after-reopen 0 "" "$loopwire" read --link "$modbus" --device tc10@3 set_point

# Each line begins with the priority journald gives its entry (sd-daemon prefixes): the lines
# down are warnings (4), which `journalctl -p warning` shows; their coming up again notices (5),
# which `-p notice` shows and `-p warning` does not.
expect furnace-down-is-a-warning grep -qE '^<4>gateway: line furnace-line \(rtu:[^)]*\) is down: ' "$WORK_DIR/gateway.log"
expect later-down-is-a-warning grep -qE '^<4>gateway: line later-line \(rtu:[^)]*\) is down: ' "$WORK_DIR/gateway.log"
expect furnace-up-is-a-notice grep -qE '^<5>gateway: line furnace-line \(rtu:[^)]*\) is up again after' "$WORK_DIR/gateway.log"
expect later-up-is-a-notice grep -qE '^<5>gateway: line later-line \(rtu:[^)]*\) is up again after' "$WORK_DIR/gateway.log"
expect up-again-is-no-warning bash -c "! grep -E '^<[0-4]>' '$WORK_DIR/gateway.log' | grep -q 'up again'"
expect the-rest-is-info grep -qE '^<6>gateway: .*listening on port' "$WORK_DIR/gateway.log"

# Logged once per change of state, not once per try: one "down" line per line that went down.
downs=$(grep -c "line furnace-line (.*) is down: " "$WORK_DIR/gateway.log")
expect_equal "$downs" 1 "'furnace-line is down' lines in the log"

# /metrics counts the down periods and the reopen attempts.
curl -sf "http://127.0.0.1:$http/metrics" >"$WORK_DIR/metrics.txt"
metrics_line() {  # REGEX : a line of /metrics matches
  grep -qE "$1" "$WORK_DIR/metrics.txt" || { grep -E '^loopwire_line_(up|down|reopen)' "$WORK_DIR/metrics.txt"; return 1; }
}
expect furnace-line-down-counted metrics_line '^loopwire_line_down_total\{line="furnace-line"\} 1$'
expect later-line-reopen-attempts-counted metrics_line '^loopwire_line_reopen_attempts_total\{line="later-line"\} [1-9]'
expect later-line-up metrics_line '^loopwire_line_up\{line="later-line"\} 1$'
requests_before=$(sed -nE 's/^loopwire_line_requests_total\{line="furnace-line"\} ([0-9]+)$/\1/p' "$WORK_DIR/metrics.txt")

# SIGHUP with only later-line retimed: furnace-line and virtual-line stay open,
# as the log says, and their figures go on (furnace-line's one down period is still counted, its
# requests keep adding up); later-line is opened afresh, its figures from nothing. The reloaded
# gateway keeps its HTTP API on the same port (port 0 in the file, [http] listen unchanged).
sed -i '/name = "later-line"/,/timeout/ s/timeout = "300ms"/timeout = "400ms"/' "$WORK_DIR/plant.toml"
kill -HUP "$gateway_pid"
wait_for_log gateway.log "configuration .*plant.toml (reloaded)" 30 >/dev/null
wait_for_log gateway.log "line furnace-line \(rtu:[^)]*\) stays (open) across the reload" 10 >/dev/null
wait_for_log gateway.log "line virtual-line \(rtu:[^)]*\) stays (open) across the reload" 10 >/dev/null
expect later-line-not-kept bash -c "! grep -q 'line later-line .* stays open' '$WORK_DIR/gateway.log'"
apis_announced() { (($(grep -c 'HTTP API and dashboard on' "$WORK_DIR/gateway.log") >= 2)); }
wait_for 30 "the reloaded gateway's HTTP API" apis_announced
http=$(grep -oE 'HTTP API and dashboard on http://127\.0\.0\.1:[0-9]+' "$WORK_DIR/gateway.log" | tail -1 | grep -oE '[0-9]+$')
api="http://127.0.0.1:$http/api/devices"
wait_for 30 "oven1 ok after the reload" status_is oven1 ok
wait_for 30 "kiln ok after the reload" status_is kiln ok
curl -sf "http://127.0.0.1:$http/metrics" >"$WORK_DIR/metrics.txt"
expect furnace-line-down-count-kept metrics_line '^loopwire_line_down_total\{line="furnace-line"\} 1$'
expect later-line-opened-afresh metrics_line '^loopwire_line_down_total\{line="later-line"\} 0$'
requests_after=$(sed -nE 's/^loopwire_line_requests_total\{line="furnace-line"\} ([0-9]+)$/\1/p' "$WORK_DIR/metrics.txt")
expect furnace-line-requests-go-on test "${requests_after:-0}" -gt "${requests_before:-0}"
check read-after-reload 0 "" "$loopwire" read --link "$modbus" --device tc10@3 set_point

finish
