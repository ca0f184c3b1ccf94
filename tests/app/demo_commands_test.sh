#!/usr/bin/env bash
# `loopwire demo` prints commands to try against the gateway it runs: each is run here exactly
# as printed (only `loopwire` replaced by the binary under test), from another "terminal",
# while the demo runs, and must do what it says.
set -u
loopwire=${1:?usage: demo_commands_test.sh path/to/loopwire}
source "$(dirname "$0")/../support/test_lib.sh"

start_background demo.log timeout 60 "$loopwire" demo --port 0 --duration 50s --format jsonl
demo_pid=$LAST_PID
port=$(wait_for_log demo.log 'Modbus TCP on tcp:..127\.0\.0\.1:([0-9]+) - try' 20)
wait_for_text "$WORK_DIR/demo.log" "--count 5" 10
mapfile -t commands < <(sed -nE 's/^  (loopwire .*)$/\1/p' "$WORK_DIR/demo.log")
expect_equal "${#commands[@]}" 5 "commands the demo prints"

cd "$WORK_DIR" || fail "no work dir"
for i in "${!commands[@]}"; do
    printed=${commands[$i]}
    read -r -a words <<<"$printed"
    [[ ${words[0]} == loopwire ]] || fail "not a loopwire command: $printed"
    [[ $printed == *"127.0.0.1:$port"* ]] || count_failure "command $i names the demo's port $port: $printed"
    status=0
    timeout 30 "$loopwire" "${words[@]:1}" >"$WORK_DIR/command-$i.out" 2>&1 || status=$?
    if [[ $status -eq 0 ]]; then count_pass; else count_failure "'$printed' exited $status" "$WORK_DIR/command-$i.out"; fi
done

# What the commands did: the reads answered with values and units, the write took, the dump is a
# document of the device, the monitor took its five samples.
check demo-read-tc10 0 "measured_value" cat "$WORK_DIR/command-0.out"
check demo-read-ac20 0 "main_set_point" cat "$WORK_DIR/command-2.out"
check demo-write-took 0 "200" "$loopwire" read --link "tcp://127.0.0.1:$port" --device tc10@3 SP
check demo-dump-document 0 "" /usr/bin/python3 -c '
import json, sys
document = json.load(open(sys.argv[1]))
assert "rampsoak" in json.dumps(document)[:2000], list(document)[:5]' "$WORK_DIR/rampsoak.json"
check demo-monitor-five-samples 0 "" /usr/bin/python3 -c '
import sys
rows = [line for line in open(sys.argv[1]) if line.startswith("{")]
assert len(rows) == 5, rows' "$WORK_DIR/command-4.out"

# The HTTP API's commands, run exactly as printed: the devices' list and one device, in JSON.
mapfile -t web_commands < <(sed -nE 's/^  (curl .*)$/\1/p' "$WORK_DIR/demo.log")
expect_equal "${#web_commands[@]}" 2 "HTTP commands the demo prints"
dashboard=$(sed -nE 's/^Its dashboard is at (http:[^ ]+) .*$/\1/p' "$WORK_DIR/demo.log")
[[ $dashboard =~ ^http://127\.0\.0\.1:[0-9]+/$ ]] && count_pass || count_failure "no dashboard address in the demo's hint"
for i in "${!web_commands[@]}"; do
    printed=${web_commands[$i]}
    read -r -a words <<<"$printed"
    [[ $printed == *"$dashboard"* ]] || count_failure "HTTP command $i names the dashboard's address $dashboard: $printed"
    status=0
    timeout 30 "${words[@]}" >"$WORK_DIR/web-$i.out" 2>&1 || status=$?
    if [[ $status -eq 0 ]]; then count_pass; else count_failure "'$printed' exited $status" "$WORK_DIR/web-$i.out"; fi
done
check demo-http-devices 0 "" /usr/bin/python3 -c '
import json, sys
devices = json.load(open(sys.argv[1]))
assert [d["name"] for d in devices] == ["furnace", "kiln", "oven"], devices' "$WORK_DIR/web-0.out"
check demo-http-device 0 "" /usr/bin/python3 -c '
import json, sys
device = json.load(open(sys.argv[1]))
assert device["name"] == "oven" and device["device"] == "tc10", device
assert any(p["name"] == "measured_value" and p["value"] is not None for p in device["parameters"]), device' "$WORK_DIR/web-1.out"
check demo-dashboard-page 0 "<html" curl -s "$dashboard"

# The demo is still running, and stops cleanly when told to (SIGTERM: a background job of a
# script has SIGINT ignored).
# (the demo itself, not `timeout` around it, which would answer for it)
pkill -TERM -P "$demo_pid"
status=0
wait "$demo_pid" || status=$?
expect_equal "$status" 0 "demo exit status after SIGTERM"
finish
