#!/usr/bin/env bash
# `loopwire dump` -> `write` -> `restore` -> `dump` against simulated ac20@1, tc10@3 and
# rampsoak@5, each served by `loopwire simulate` on its own loopback TCP port: the dry run lists
# exactly what was changed and writes nothing, the restore brings back every restored word, and
# a restore into an AC20 it cannot enter configuration mode of, a dump of another profile and a
# file that is not a dump all fail cleanly.
#
# Which words must come back: every parameter the dump marks writable, except procedure words
# restore never writes (AC20 mode-entry/command words and bit 218, restore_plan.hpp) and the
# values the process itself moves. The latter are found by rule, not listed: a writable word
# that differs between two dumps of the untouched device, taken one after the other, is moved
# by the process (outputs, timers), and so are the AC20 outputs 130-132 and TC10 output power,
# which the controller overwrites every cycle in automatic mode. Restore itself writes only
# stored words (profile "storage": "persistent"): the AC20 dry run below lists exactly the five
# changed parameters, not the outputs 130/132 that moved meanwhile.
set -u
loopwire=${1:?usage: restore_test.sh path/to/loopwire}
source "$(dirname "$0")/../support/test_lib.sh"
python=/usr/bin/python3

serve() {  # device -> sets $served to the link URL of a simulator serving it alone
  local device=$1
  start_tcp_server "$device.sim.log" "$loopwire" simulate --link tcp://127.0.0.1:0 --device "$device" --duration 170s
  served="tcp://127.0.0.1:$PORT"
}

dump() {  # link device file
  timeout 60 "$loopwire" dump --link "$1" --device "$2" --output "$3" >"$WORK_DIR/dump.out" 2>&1 \
    || { echo "FAIL dump $2 to $3:"; sed 's/^/    /' "$WORK_DIR/dump.out"; failures=$((failures + 1)); }
}

# Exits non-zero, printing why, when the two dumps differ in a compared word.
# args: first-dump second-dump [baseline-dump-for-process-moved-words]
same_words() {
  $python - "$@" <<'PY'
import json, sys
first, second = (json.load(open(p))["parameters"] for p in sys.argv[1:3])
moved = set()
if len(sys.argv) > 3:
    baseline = json.load(open(sys.argv[3]))["parameters"]
    moved = {n for n in first if first[n]["raw"] != baseline[n]["raw"]}
procedure = {"local_remote", "configuration_mode_code", "security_mode_code", "control_lock_code"}
driven = {"main_output_value", "secondary_output_value", "pid_output_value", "output_power"}
compared = [n for n, e in first.items() if e["writable"] and n not in procedure | driven | moved]
assert len(compared) > 20, compared
differing = [(n, first[n]["raw"], second[n]["raw"]) for n in compared if first[n]["raw"] != second[n]["raw"]]
assert not differing, differing
PY
}

# The names a dry run lists, one per line ("  name   old -> new"). TC10 output_power moves
# once SP changes, but it is RAM (profile note, §5): restore neither lists nor writes it.
listed() { sed -n 's/^  \([a-z0-9_]*\) .* -> .*/\1/p' "$1" | sort; }

restore_round_trip() {  # device link change-function expected-names...
  local device=$1 link=$2 change=$3; shift 3
  local id=${device%@*}
  dump "$link" "$device" "$WORK_DIR/$id.before.json"
  dump "$link" "$device" "$WORK_DIR/$id.baseline.json"
  "$change" "$link"
  dump "$link" "$device" "$WORK_DIR/$id.changed.json"

  timeout 60 "$loopwire" restore --link "$link" --device "$device" "$WORK_DIR/$id.before.json" --dry-run >"$WORK_DIR/$id.dry.out" 2>&1
  local status=$?
  local want; want=$(printf '%s\n' "$@" | sort)
  if [ "$status" -eq 0 ] && [ "$(listed "$WORK_DIR/$id.dry.out")" = "$want" ] && grep -q "dry run: nothing written" "$WORK_DIR/$id.dry.out"
  then passes=$((passes + 1))
  else echo "FAIL $id-dry-run-lists-exactly-the-changes (status $status; want: $(echo $want))"; sed 's/^/    /' "$WORK_DIR/$id.dry.out"; failures=$((failures + 1)); fi
  dump "$link" "$device" "$WORK_DIR/$id.after-dry.json"
  if same_words "$WORK_DIR/$id.changed.json" "$WORK_DIR/$id.after-dry.json" "$WORK_DIR/$id.before.json" >"$WORK_DIR/why" 2>&1; then passes=$((passes + 1))
  else echo "FAIL $id-dry-run-writes-nothing"; sed 's/^/    /' "$WORK_DIR/why"; failures=$((failures + 1)); fi

  check "$id-restore" 0 "every value read back as written" \
    "$loopwire" restore --link "$link" --device "$device" "$WORK_DIR/$id.before.json" --yes
  dump "$link" "$device" "$WORK_DIR/$id.after.json"
  if same_words "$WORK_DIR/$id.before.json" "$WORK_DIR/$id.after.json" "$WORK_DIR/$id.baseline.json" >"$WORK_DIR/why" 2>&1; then passes=$((passes + 1))
  else echo "FAIL $id-restore-brings-back-every-word"; sed 's/^/    /' "$WORK_DIR/why"; failures=$((failures + 1)); fi
}

serve ac20@1; ac20=$served
serve tc10@3; tc10=$served
serve rampsoak@5; rampsoak=$served

# AC20: control parameters, and configuration parameters of two menus (Notes 5-7: remote, then
# configuration mode with word 347, each menu closed with its end word, back with word 3051).
# `loopwire write` checks the mode before sending, so each mode step is its own call. Note 5:
# after 3 s without line activity the unit returns to local mode; a background monitor polls it
# every 500 ms meanwhile, as a SCADA would, so a slow machine (sanitizers, load) does not fall
# out of remote between two calls.
ac20_steps() {  # name link assignments...: one write call each, in order
  local name=$1 link=$2; shift 2
  start_background "$name.keep-alive.log" timeout 120 "$loopwire" monitor --link "$link" --device ac20@1 device_status \
    --interval 500ms --count 240
  local keep_alive=$LAST_PID
  wait_for 20 "the keep-alive monitor's first sample" test -s "$WORK_DIR/$name.keep-alive.log"
  for assignment in "$@"; do
    check "$name $assignment" 0 "" "$loopwire" write --link "$link" --device ac20@1 "$assignment"
  done
  kill "$keep_alive" 2>/dev/null
  wait "$keep_alive" 2>/dev/null
}
change_ac20() {
  ac20_steps ac20-write-configuration "$1" local_remote=remote configuration_mode_code=0 probe_input_filter=7 \
    end_configuration_menu_1=1 bar_graph_high=1.50 end_configuration_menu_6=1 enable_control_mode=1
  ac20_steps ac20-write-control "$1" local_remote=remote auxiliary_set_point_2=1.25 proportional_band=55 integral_time=97
}
restore_round_trip ac20@1 "$ac20" change_ac20 \
  auxiliary_set_point_2 proportional_band integral_time probe_input_filter bar_graph_high

# TC10: bounded values (SP within SP.LL..SP.HL, §5.3.8): SP.HL lowered to 150 (after SP to 100,
# so it fits) is restored with SP, each within its bounds when written. Word 6 (set_point_var, §5.1) is SP seen in
# the variables area, so it differs too.
change_tc10() {
  check tc10-write 0 "" "$loopwire" write --link "$1" --device tc10@3 set_point=100 set_point_high_limit=150 \
    alarm_1_threshold=40 proportional_band=33
}
restore_round_trip tc10@3 "$tc10" change_tc10 set_point set_point_var set_point_high_limit alarm_1_threshold proportional_band

# AC20 with a configuration lock combination (set in security code mode, Note 8): a restore
# with the wrong --lock-code is refused at word 347 (exception 3), writes nothing, says so, and
# leaves the device in control mode (word 135 = 0); the right one restores.
ac20_steps ac20-set-lock "$ac20" local_remote=remote security_mode_code=0 configuration_lock_combination=77 enable_control_mode=1
ac20_steps ac20-change-under-lock "$ac20" local_remote=remote configuration_mode_code=77 probe_input_filter=9 \
  end_configuration_menu_1=1 enable_control_mode=1
ac20_steps ac20-change-control "$ac20" local_remote=remote auxiliary_set_point_2=1.35
timeout 30 "$loopwire" restore --link "$ac20" --device ac20@1 "$WORK_DIR/ac20.before.json" --yes --lock-code 13 >"$WORK_DIR/lock.out" 2>&1
status=$?
if [ "$status" -ne 0 ] && grep -q "restore stopped:.*347\|restore stopped:.*configuration_mode_code" "$WORK_DIR/lock.out" \
   && grep -q "written: nothing" "$WORK_DIR/lock.out" && grep -q "not written: .*probe_input_filter" "$WORK_DIR/lock.out" \
   && grep -q "not written: .*auxiliary_set_point_2" "$WORK_DIR/lock.out"
then passes=$((passes + 1)); else echo "FAIL ac20-wrong-lock-code-fails-cleanly (status $status)"; sed 's/^/    /' "$WORK_DIR/lock.out"; failures=$((failures + 1)); fi
check ac20-after-wrong-lock-in-control-mode 0 '"raw":0' "$loopwire" read --link "$ac20" --device ac20@1 device_status --json
check ac20-wrong-lock-wrote-nothing 0 '"raw":9' "$loopwire" read --link "$ac20" --device ac20@1 probe_input_filter --json
check ac20-right-lock-restores 0 "every value read back as written" \
  "$loopwire" restore --link "$ac20" --device ac20@1 "$WORK_DIR/ac20.before.json" --yes --lock-code 77

change_rampsoak() {
  check rampsoak-write 0 "" "$loopwire" write --link "$1" --device rampsoak@5 SV=425 out1_proportional_band=77 alarm_1_mode=3
}
restore_round_trip rampsoak@5 "$rampsoak" change_rampsoak set_value out1_proportional_band alarm_1_mode

# A dump of another profile is refused unless --force (then only the names both share count:
# the ramp/soak and the TC10 share decimal_point and baud_rate);
# a file that is not a dump is a clear usage error.
check other-profile-refused 2 "the dump is of a ac20, the device is a tc10; add --force" \
  "$loopwire" restore --link "$tc10" --device tc10@3 "$WORK_DIR/ac20.before.json" --dry-run
check other-profile-forced 0 "dry run: nothing written" \
  "$loopwire" restore --link "$tc10" --device tc10@3 "$WORK_DIR/rampsoak.before.json" --dry-run --force
echo '{"parameters": {}}' >"$WORK_DIR/plain.json"
check not-a-dump 2 "is not a loopwire dump" "$loopwire" restore --link "$tc10" --device tc10@3 "$WORK_DIR/plain.json" --dry-run
echo 'SP=100' >"$WORK_DIR/notes.txt"
check not-json 2 "is not valid JSON" "$loopwire" restore --link "$tc10" --device tc10@3 "$WORK_DIR/notes.txt" --dry-run

finish
