#!/usr/bin/env bash
# The simulated process seen through the CLI only: `loopwire simulate --speed 200` serves a
# device's behaviour model on a pseudo-terminal, `loopwire write --device` changes its set
# point, and `loopwire read --device --json` is polled until the process value settles there.
# Then a fault (--fault) shows in what `read` reports, and --seed makes two runs repeat.
set -u
loopwire=${1:?usage: simulated_process_test.sh path/to/loopwire}
python=/usr/bin/python3
source "$(dirname "$0")/../support/test_lib.sh"

start() {  # pty-name, simulate arguments...: serves until the script ends
  local name=$1; shift
  start_background "$name.log" "$loopwire" simulate --pty "$WORK_DIR/$name" "$@" --duration 60s
  wait_for_path "$WORK_DIR/$name"
}

# The JSON "value" (or, with a third argument, another field) of one parameter, or "none".
field() {  # pty-name, DEVICE@UNIT, parameter [field]
  timeout 5 "$loopwire" read --link "rtu:$WORK_DIR/$1" --device "$2" "$3" --json 2>/dev/null |
    $python -c "import json,sys
try: print(json.load(sys.stdin)['values']['$3']['${4:-value}'])
except Exception: print('none')"
}

# Polls `parameter` until it is within `tolerance` of `target` for 3 reads in a row, at most
# `seconds` of real time; passes or fails with the last values seen.
settles() {  # name, pty-name, DEVICE@UNIT, parameter, target, tolerance, seconds
  local name=$1 pty=$2 device=$3 parameter=$4 target=$5 tolerance=$6 seconds=$7
  local end=$((SECONDS + seconds)) inside=0 seen=""
  while [ $SECONDS -lt $end ] && [ $inside -lt 3 ]; do
    local value; value=$(field "$pty" "$device" "$parameter")
    seen="$seen $value"
    if $python -c "import sys; sys.exit(0 if abs(float('$value') - $target) <= $tolerance else 1)" 2>/dev/null; then
      inside=$((inside + 1))
    else
      inside=0
    fi
    sleep 0.3
  done
  if [ $inside -ge 3 ]; then passes=$((passes + 1)); else
    echo "FAIL $name: $parameter never settled within $tolerance of $target; read:$seen"
    failures=$((failures + 1))
  fi
}

# --- TC10 (unit 3): measured value (word 1) follows the set point (717) under PID control.
start ttyT --device tc10@3 --speed 200
check tc10-write-set-point 0 "wrote set_point = 300" "$loopwire" write --link "rtu:$WORK_DIR/ttyT" --device tc10@3 set_point=300
settles tc10-settles-at-set-point ttyT tc10@3 measured_value 300 2 20

# --- Ramp/soak (unit 5): PV (008Ah) follows SV (0000h).
start ttyR --device rampsoak@5 --speed 200
check rampsoak-write-set-value 0 "wrote set_value = 150" "$loopwire" write --link "rtu:$WORK_DIR/ttyR" --device rampsoak@5 set_value=150
settles rampsoak-settles-at-set-value ttyR rampsoak@5 process_value 150 1 20

# --- AC20 (unit 1): remote first (bit 218, Note 5), then the carbon potential follows SP.
start ttyA --device ac20@1 --speed 200
# One command: the mode check sees that the first assignment puts the device in remote.
check ac20-write-remote-and-set-point 0 "wrote main_set_point = 0.9" \
  "$loopwire" write --link "rtu:$WORK_DIR/ttyA" --device ac20@1 local_remote=remote main_set_point=0.9
settles ac20-settles-at-set-point ttyA ac20@1 carbon_potential 0.9 0.03 20

# --- Faults: an open TC10 input reads over-range (§5.1 1A), an open ramp/soak input
# lights the IN1E message of OBIT (§7, 0088H).
start ttyF --device tc10@3 --fault tc10@3:open-input
check tc10-open-input-is-out-of-range 0 "out-of-range (raw 10000)" "$loopwire" read --link "rtu:$WORK_DIR/ttyF" --device tc10@3 measured_value
start ttyG --device rampsoak@5 --fault rampsoak@5:open-input
check rampsoak-open-input-shows 0 "{Message IN1E}" "$loopwire" read --link "rtu:$WORK_DIR/ttyG" --device rampsoak@5 controller_status

finish
