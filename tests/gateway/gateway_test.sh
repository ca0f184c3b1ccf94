#!/usr/bin/env bash
# `loopwire gateway` in front of simulated devices on a pseudo-terminal line: Modbus TCP clients
# (loopwire itself, mbpoll on libmodbus, a raw socket) read and write through it at the same
# time; a unit no line serves gets exception 0Ah, a configured unit that stays silent 0Bh, a
# read-only gateway refuses writes with exception 1; `--check` prints the plan, and a broken
# configuration is refused naming the file, the line and the key.
set -u
loopwire=${1:?usage: gateway_test.sh path/to/loopwire}
source "$(dirname "$0")/../support/test_lib.sh"
python=/usr/bin/python3

pty="$WORK_DIR/ttyG0"
start_background sim.log "$loopwire" simulate --link "rtu:/unused?baud=19200&parity=none" --pty "$pty" \
  --device tc10@3 --device rampsoak@5 --duration 280s  # the whole test, sanitized builds too (ctest: 300 s)
wait_for_path "$pty"

write_config() {  # FILE WRITES : a gateway for the line with oven1 (tc10@3), kiln (rampsoak@5),
                  # and absent (tc10@4, which nothing on the line answers for)
  cat >"$1" <<TOML
[[lines]]
name = "furnace-line"
link = "rtu:$pty?baud=19200&parity=none"
timeout = "300ms"

[[lines.devices]]
name = "oven1"
device = "tc10@3"

[[lines.devices]]
name = "kiln"
device = "rampsoak@5"

[[lines.devices]]
name = "absent"
device = "tc10@4"

[modbus_tcp]
listen = "127.0.0.1:0"
writes = $2

[log]
statistics = "1s"
TOML
}
write_config "$WORK_DIR/plant.toml" true

# docs/gateway-configuration.md's command, as printed, from the repository's top folder.
check readme-plan 0 "estimated line load" bash -c "cd '$(dirname "$0")/../..' && '$loopwire' gateway --config examples/plant.toml --check"

check plan-names-the-line 0 "furnace-line" "$loopwire" gateway --config "$WORK_DIR/plant.toml" --check
check plan-gives-the-load 0 "estimated line load" "$loopwire" gateway --config "$WORK_DIR/plant.toml" --check

start_tcp_server gateway.log timeout 250 "$loopwire" gateway --config "$WORK_DIR/plant.toml"
gateway="tcp://127.0.0.1:$PORT"
gateway_port=$PORT

# By name, through the gateway, with loopwire's own TCP master.
check write-through-the-gateway 0 "" "$loopwire" write --link "$gateway" --device tc10@3 set_point=150
check read-back-through-the-gateway 0 '"value":150' "$loopwire" read --link "$gateway" --device tc10@3 set_point --json
check rampsoak-through-the-gateway 0 "" "$loopwire" write --link "$gateway" --device rampsoak@5 SV=321

# mbpoll (libmodbus) as a SCADA would: TCP, unit 5, the ramp/soak SV at 0000h.
mbpoll_out=$(timeout 10 mbpoll -m tcp -p "$gateway_port" -a 5 -0 -1 -r 0 -c 1 127.0.0.1 2>&1)
if grep -qE '^\[0\]:[[:space:]]+321' <<<"$mbpoll_out"; then count_pass; else echo "FAIL mbpoll-reads-through-the-gateway"; echo "$mbpoll_out" | sed 's/^/    /'; failures=$((failures + 1)); fi

# Three clients at once, each 20 reads: every one answered right. Right, not fast: a read may
# wait behind a poll of the absent unit timing out and its late-reply window, which under a
# sanitizer's slowdown passes the 1 s default timeout.
concurrent_reads() {  # NAME : 20 reads of tc10@3 set_point, each must say 150
  local i
  for i in $(seq 20); do
    local out
    out=$("$loopwire" read --link "$gateway" --timeout 10s --device tc10@3 set_point --json 2>&1)
    grep -q '"value":150' <<<"$out" || { echo "$1: read $i wrong: $out"; return 1; }
  done
}
concurrent_reads a >"$WORK_DIR/a.out" & a=$!
concurrent_reads b >"$WORK_DIR/b.out" & b=$!
concurrent_reads c >"$WORK_DIR/c.out" & c=$!
if wait $a && wait $b && wait $c; then count_pass; else count_failure clients-at-once "$WORK_DIR/a.out" "$WORK_DIR/b.out" "$WORK_DIR/c.out"; fi

# Exceptions a gateway gives (Modbus application protocol V1.1b3, 7).
check unserved-unit-gets-0Ah 5 "exception 10" "$loopwire" read --link "$gateway" --unit 9 holding 0
check silent-unit-gets-0Bh 5 "exception 11" "$loopwire" read --link "$gateway" --unit 4 holding 0
# A scan through the gateway counts the devices behind it, not the units it answers for: 3 and 5
# answer, 4 (silent, 0Bh) and the unserved ones (0Ah) are nobody.
"$loopwire" scan --link "$gateway" --units 1-6 --timeout 2s >"$WORK_DIR/scan.out" 2>"$WORK_DIR/scan.err"
check scan-through-gateway-counts-devices 0 "2 unit(s) answered" cat "$WORK_DIR/scan.out"
check scan-through-gateway-says-why-not-more 0 "4 unit(s) were answered by a gateway with exception 0Ah or 0Bh" cat "$WORK_DIR/scan.err"

# A function code loopwire's typed master never sends goes through as it is: the TC10 answers
# function 65 (user-defined) with exception 1, and the gateway hands that back unchanged.
$python - "$gateway_port" >"$WORK_DIR/raw.out" 2>&1 <<'PY'
import socket, sys
s = socket.create_connection(("127.0.0.1", int(sys.argv[1])), timeout=5)
s.sendall(bytes([0x12, 0x34, 0, 0, 0, 3, 3, 0x41, 0x00]))
reply = b""
while len(reply) < 9:
    chunk = s.recv(64)
    if not chunk:
        break
    reply += chunk
print(reply.hex(" "))
assert reply[:2] == b"\x12\x34", "transaction id not kept"
assert reply[6] == 3 and reply[7] == 0xC1, "not the device's exception reply to function 65"
PY
if [[ $? -eq 0 ]]; then count_pass; else count_failure any-function-code-passes-through "$WORK_DIR/raw.out"; fi

# The gateway's own polls (every device's default watch list, each second) share the line with
# the clients above; a device that answers and one that does not are logged once each.
wait_for 30 "oven1 polled" grep -q "device oven1 (tc10@3) answers" "$WORK_DIR/gateway.log"
wait_for 30 "kiln polled" grep -q "device kiln (rampsoak@5) answers" "$WORK_DIR/gateway.log"
# A device going silent is a warning (`journalctl -p warning` shows it); one answering is info.
wait_for 30 "the silent unit noticed" grep -qE "Z warning loopwire: gateway: device absent \(tc10@4\) does not answer" "$WORK_DIR/gateway.log"
if grep -qE "Z info loopwire: gateway: device oven1 \(tc10@3\) answers" "$WORK_DIR/gateway.log"; then count_pass
else count_failure answering-is-info "$WORK_DIR/gateway.log"; fi
count_pass
# Statistics every second ([log] statistics = "1s"), each line's busy share over that second,
# every log line stamped with its UTC time and level.
wait_for 30 "periodic statistics" grep -qE "^[0-9]{4}-[0-9]{2}-[0-9]{2}T[0-9:.]+Z info .*line furnace-line .* sent, .* garbled frame\(s\), .*busy [0-9.]+ % over the last 1 s" "$WORK_DIR/gateway.log"
count_pass

# SIGTERM drains: a request sent just before it (to the silent unit: 300 ms of waiting on the
# line) is still answered, with 0Bh, and the gateway exits 0.
$python - "$gateway_port" "$LAST_PID" >"$WORK_DIR/drain.out" 2>&1 <<'PY'
import os, signal, socket, struct, sys, time
s = socket.create_connection(("127.0.0.1", int(sys.argv[1])), timeout=5)
s.sendall(struct.pack(">HHHB", 7, 0, 6, 4) + bytes([3, 0, 0, 0, 1]))
time.sleep(0.1)  # on the line now
os.kill(int(sys.argv[2]), signal.SIGTERM)
reply = s.recv(64)
print(reply.hex(" "))
assert reply == struct.pack(">HHHB", 7, 0, 3, 4) + bytes([0x83, 0x0B]), "no 0Bh reply after SIGTERM"
PY
if [[ $? -eq 0 ]]; then count_pass; else count_failure sigterm-drains "$WORK_DIR/drain.out"; fi
wait "$LAST_PID"
gateway_status=$?
if [[ $gateway_status -eq 0 ]]; then count_pass; else echo "FAIL sigterm-exit-status: $gateway_status"; failures=$((failures + 1)); fi
if grep -qE "line furnace-line .*: [1-9][0-9]* sent, [1-9][0-9]* answered, [1-9][0-9]* timeout" "$WORK_DIR/gateway.log"; then count_pass
else count_failure statistics-at-exit "$WORK_DIR/gateway.log"; fi

# writes = false: reads pass, writes get exception 1 and are logged.
write_config "$WORK_DIR/read-only.toml" false
start_tcp_server read-only.log timeout 60 "$loopwire" gateway --config "$WORK_DIR/read-only.toml"
read_only="tcp://127.0.0.1:$PORT"
check read-only-gateway-reads 0 '"value":150' "$loopwire" read --link "$read_only" --device tc10@3 set_point --json
check read-only-gateway-refuses-writes 5 "exception 1" "$loopwire" write --link "$read_only" --device tc10@3 set_point=160
check refused-write-was-not-made 0 '"value":150' "$loopwire" read --link "$read_only" --device tc10@3 set_point --json
if grep -q "read-only" "$WORK_DIR/read-only.log"; then count_pass; else count_failure refused-write-is-logged "$WORK_DIR/read-only.log"; fi

# SIGHUP re-reads the file: writes allowed now. Port 0 in the file: the reloaded gateway listens
# on a new port, which it names like the first.
read_only_pid=$(pgrep -P "$LAST_PID")  # the gateway itself, not `timeout` around it (which forwards one signal only)
last_port() { grep -oE 'listening on port [0-9]+' "$WORK_DIR/read-only.log" | tail -1 | grep -oE '[0-9]+$'; }
write_config "$WORK_DIR/read-only.toml" true
kill -HUP "$read_only_pid"
wait_for 30 "the reload" grep -q "configuration .*read-only.toml reloaded" "$WORK_DIR/read-only.log"
# A function, so the count is taken again on every try (a "$(grep -c ...)" argument would be
# counted once, before the first try, and miss a port logged a moment after the reload line).
ports_announced() { (($(grep -c 'listening on port' "$WORK_DIR/read-only.log") >= 2)); }
wait_for 30 "the reloaded gateway's port" ports_announced
reloaded="tcp://127.0.0.1:$(last_port)"
check reloaded-gateway-takes-writes 0 "" "$loopwire" write --link "$reloaded" --device tc10@3 set_point=160
check reloaded-gateway-wrote 0 '"value":160' "$loopwire" read --link "$reloaded" --device tc10@3 set_point --json
# A broken file on SIGHUP: said why, and the running gateway goes on serving.
printf '[[lines]]\nname = "x"\nlink = 7\n' >"$WORK_DIR/read-only.toml"
kill -HUP "$read_only_pid"
wait_for 30 "the refused reload" grep -q "configuration not reloaded, the running one is kept: .*read-only.toml:3: lines\[0\].link" "$WORK_DIR/read-only.log"
check still-serving-after-a-bad-reload 0 '"value":160' "$loopwire" read --link "$reloaded" --device tc10@3 set_point --json
write_config "$WORK_DIR/read-only.toml" false

kill -TERM "$LAST_PID"  # the line is the gateway's alone: free it for the next one
wait "$LAST_PID" 2>/dev/null

# Under systemd (Type=notify, WatchdogSec=): READY=1 once serving, WATCHDOG=1 again and again
# (every half of WATCHDOG_USEC), STOPPING=1 on SIGTERM, exit status 0.
notify="$WORK_DIR/notify.sock"
$python - "$notify" >"$WORK_DIR/notify.out" 2>&1 <<'PY' &
import socket, sys
sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
sock.bind(sys.argv[1])
sock.settimeout(30)
while True:
    message = sock.recv(4096).decode().replace("\n", " ")
    print(message, flush=True)
    if "STOPPING=1" in message:
        break
PY
listener=$!
wait_for_path "$notify"
NOTIFY_SOCKET="$notify" WATCHDOG_USEC=200000 "$loopwire" gateway --config "$WORK_DIR/read-only.toml" >"$WORK_DIR/notified.log" 2>&1 &
notified=$!
wait_for 30 "READY=1 from the gateway" grep -q "READY=1" "$WORK_DIR/notify.out"
pinged_twice() { [ "$(grep -c "WATCHDOG=1" "$WORK_DIR/notify.out")" -ge 2 ]; }
wait_for 30 "WATCHDOG=1 twice from the gateway" pinged_twice
kill -TERM "$notified"
wait "$notified"
status=$?
wait "$listener"
if [[ $status -eq 0 ]] && grep -q "STATUS=serving 1 line(s), 3 device(s)" "$WORK_DIR/notify.out" && grep -q "STOPPING=1" "$WORK_DIR/notify.out"
then count_pass; else echo "FAIL systemd-notify (exit $status)"; cat "$WORK_DIR/notify.out" "$WORK_DIR/notified.log"; failures=$((failures + 1)); fi

# The unit file systemd would load, with ExecStart pointed at the binary under test, and its
# Documentation= pages (verify runs man on each) the ones the build wrote beside it.
sed "s#^ExecStart=/usr/bin/loopwire #ExecStart=$(realpath "$loopwire") #" "$(dirname "$0")/../../packaging/loopwire-gateway.service" \
  >"$WORK_DIR/loopwire-gateway.service"
verify_out=$(MANPATH="$(dirname "$(realpath "$loopwire")")/man" timeout 20 systemd-analyze verify "$WORK_DIR/loopwire-gateway.service" 2>&1); verify_status=$?
if [[ $verify_status -eq 0 && -z $verify_out ]]; then count_pass; else echo "FAIL unit-file-verifies (exit $verify_status)"; echo "$verify_out" | sed 's/^/    /'; failures=$((failures + 1)); fi

# A broken configuration: refused before anything opens, naming file, line and key.
cat >"$WORK_DIR/broken.toml" <<TOML
[[lines]]
name = "furnace-line"
link = "rtu:$pty"
timeout = "fast"
TOML
check broken-config-names-file-line-key 2 "broken.toml:4" "$loopwire" gateway --config "$WORK_DIR/broken.toml" --check
check missing-config 2 "nowhere.toml" "$loopwire" gateway --config "$WORK_DIR/nowhere.toml"
# Six mistakes in six tables: one run of --check says each at its line, then their count; a start
# refuses the file with the same list.
cat >"$WORK_DIR/six.toml" <<TOML
[[lines]]
name = "furnace-line"
link = "rtu:$pty"
timeout = "fast"

[[lines.devices]]
name = "oven1"
device = "tc10@3"

[[lines.devices]]
name = "oven1"
device = "tc10@4"

[modbus_tcp]
listen = "127.0.0.1:99999"

[log]
file = "gateway.log"

[mqtt]
broker = "mqtt://127.0.0.1:1883"
max_payload = 8

[http]
read_timeout = "1ms"
TOML
six_mistakes() {  # COMMAND... : passes when its output is the six mistakes, at their lines, and the count
  local out status=0
  out=$("$@" 2>&1) || status=$?
  local lines
  lines=$(sed -n 's/^\(loopwire: error: \)\{0,1\}[^ ]*six\.toml:\([0-9]*\): \([^:]*\):.*/\2 \3/p' <<<"$out" | tr '\n' ' ')
  if [[ $status -eq 2 && $lines == "4 lines[0].timeout 11 lines[0].devices[1].name 15 modbus_tcp.listen 18 log.file 22 mqtt.max_payload 25 http.read_timeout " && $(tail -n 1 <<<"$out") == "6 mistakes in $WORK_DIR/six.toml" ]]; then
    count_pass
  else
    echo "FAIL six-mistakes: $* (exit $status), output:"; echo "$out" | sed 's/^/    /'; failures=$((failures + 1))
  fi
}
six_mistakes timeout 20 "$loopwire" gateway --config "$WORK_DIR/six.toml" --check
six_mistakes timeout 20 "$loopwire" gateway --config "$WORK_DIR/six.toml"
# A history database in a folder that is not there: --check says so with file:line, and so does a
# start, before any line opens.
cat >"$WORK_DIR/history.toml" <<TOML
[[lines]]
name = "furnace-line"
link = "rtu:$pty"

[[lines.devices]]
name = "oven"
device = "tc10@3"

[history]
database = "no-such-folder/plant.db"
TOML
check history-folder-missing-at-check 2 "history.toml:10: history.database: the folder $WORK_DIR/no-such-folder does not exist" \
  "$loopwire" gateway --config "$WORK_DIR/history.toml" --check
check history-folder-missing-at-start 2 "mkdir -p $WORK_DIR/no-such-folder" "$loopwire" gateway --config "$WORK_DIR/history.toml"

# docs/gateway-configuration.md's two commands, as printed, in a scratch folder: the complete example that
# --print-config writes passes --check unchanged (it also names every key: the man page test).
check readme-print-config 0 "" bash -c "cd '$WORK_DIR' && '$loopwire' gateway --print-config > gateway.toml"
check print-config-passes-check 0 "gateway.toml: 1 line" bash -c "cd '$WORK_DIR' && '$loopwire' gateway --config gateway.toml --check"
check print-config-names-every-table 0 "[[lines.devices]]" cat "$WORK_DIR/gateway.toml"
check gateway-without-config 2 "--print-config > gateway.toml" "$loopwire" gateway
check print-config-is-not-check 2 "excludes" "$loopwire" gateway --print-config --check
check print-config-reads-no-file 2 "excludes" "$loopwire" gateway --print-config --config "$WORK_DIR/gateway.toml"

finish
