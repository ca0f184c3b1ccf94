#!/usr/bin/env bash
# `loopwire simulate` options beyond serving: --state keeps non-volatile contents across
# restarts (and refuses files that are not its own), --fault and --speed are checked.
set -u
loopwire=${1:?usage: simulate_options_test.sh path/to/loopwire}
source "$(dirname "$0")/../support/test_lib.sh"

state="$WORK_DIR/state.json"
start_tc10() {  # pty-name: serves tc10@3 with the state file until killed
  start_background "$1.log" "$loopwire" simulate --pty "$WORK_DIR/$1" --link "rtu:$WORK_DIR/$1?parity=none" --device tc10@3 \
    --state "$state" --duration 60s
  wait_for_path "$WORK_DIR/$1"
}

# A value written over the wire survives a restart of the simulator through the state file.
start_tc10 ttyA
check state-write 0 "wrote set_point = 150" "$loopwire" write --link "rtu:$WORK_DIR/ttyA?parity=none" --device tc10@3 set_point=150
# §5.1 16A: the remote set point lives in RAM only; it must not come back after a restart.
check state-write-ram-only 0 "wrote remote_set_point = 120" "$loopwire" write --link "rtu:$WORK_DIR/ttyA?parity=none" --device tc10@3 remote_set_point=120
# The state file follows within a quarter second.
wait_for 5 "set_point 150 in the state file" grep -q '"set_point": 150' "$state"
kill "$LAST_PID"; wait "$LAST_PID" 2>/dev/null
check state-file-holds-value 0 '"set_point": 150' cat "$state"
start_tc10 ttyB
check state-restored-after-restart 0 "(raw 150)" "$loopwire" read --link "rtu:$WORK_DIR/ttyB?parity=none" --device tc10@3 set_point
check state-ram-only-lost-at-restart 0 "(raw 0)" "$loopwire" read --link "rtu:$WORK_DIR/ttyB?parity=none" --device tc10@3 remote_set_point
check state-file-has-no-ram-only-value 1 "" grep -q '"remote_set_point"' "$state"
kill "$LAST_PID"; wait "$LAST_PID" 2>/dev/null

# AC20 Note 5: "At power up, the slave will be in local mode if it was in control mode at power
# off. In the other cases, it will maintain the condition it was at the power off." Configuration
# mode, entered over the wire, is in the state file and comes back after a restart.
ac20_state="$WORK_DIR/ac20-state.json"
start_ac20() {  # pty-name
  start_background "$1.log" "$loopwire" simulate --pty "$WORK_DIR/$1" --link "rtu:$WORK_DIR/$1" --device ac20@4 \
    --state "$ac20_state" --duration 60s
  wait_for_path "$WORK_DIR/$1"
}
start_ac20 ttyJ
check ac20-state-enter-configuration 0 "wrote" "$loopwire" write --link "rtu:$WORK_DIR/ttyJ" --device ac20@4 \
  local_remote=1 configuration_mode_code=0
wait_for 5 "the configuration mode in the state file" grep -q '"mode": 1' "$ac20_state"
kill "$LAST_PID"; wait "$LAST_PID" 2>/dev/null
start_ac20 ttyK
check ac20-state-configuration-mode-kept 0 "(raw 6)" "$loopwire" read --link "rtu:$WORK_DIR/ttyK" --device ac20@4 device_status
kill "$LAST_PID"; wait "$LAST_PID" 2>/dev/null

# Files that are not a state file are refused and left untouched.
echo '{"format": "something-else"}' >"$WORK_DIR/other.json"
check state-foreign-file 2 "is not a loopwire simulator state file" \
  "$loopwire" simulate --pty "$WORK_DIR/ttyC" --device tc10@3 --state "$WORK_DIR/other.json" --duration 1s
check state-foreign-file-untouched 0 "something-else" cat "$WORK_DIR/other.json"
echo '{ not json' >"$WORK_DIR/broken.json"
check state-broken-json 2 "is not valid JSON" \
  "$loopwire" simulate --pty "$WORK_DIR/ttyD" --device tc10@3 --state "$WORK_DIR/broken.json" --duration 1s
check state-unwritable-dir 2 "creating a temporary file failed" \
  "$loopwire" simulate --pty "$WORK_DIR/ttyE" --device tc10@3 --state "$WORK_DIR/no/such/dir/state.json" --duration 1s

# --fault and --speed are checked before anything is served.
check fault-unknown-name 2 "knows no fault 'melted'" \
  "$loopwire" simulate --pty "$WORK_DIR/ttyF" --device tc10@3 --fault tc10@3:melted --duration 1s
check fault-unserved-unit 2 "unit 4 is not simulated as tc10" \
  "$loopwire" simulate --pty "$WORK_DIR/ttyG" --device tc10@3 --fault tc10@4:open-input --duration 1s
check fault-no-colon 2 "write DEVICE@UNIT:FAULT" \
  "$loopwire" simulate --pty "$WORK_DIR/ttyH" --device tc10@3 --fault tc10@3 --duration 1s
check speed-out-of-range 2 "--speed" "$loopwire" simulate --pty "$WORK_DIR/ttyI" --device tc10@3 --speed 0 --duration 1s
# A negative seed is refused, not wrapped round to 18446744073709551615.
check seed-negative 2 "--seed" "$loopwire" simulate --pty "$WORK_DIR/ttyL" --device tc10@3 --seed -1 --duration 1s

finish
