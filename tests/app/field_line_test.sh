#!/usr/bin/env bash
# Field-ready serial lines, through the real binary on pseudo-terminals:
# - `scan --emit-config FILE` against three simulated controllers and a plain register bank on
#   one line writes a gateway configuration that `gateway --config FILE --check` passes, with a
#   device per identified unit and a comment for the unit it could not identify;
# - rs485 in the link URL: true refuses a port without kernel RS-485 control (a pseudo-terminal)
# - rs485 = true in a gateway's line: --check refuses such a port, "auto" passes
#   and says what to do; auto runs without it and says so on stderr.
set -u
loopwire=${1:?usage: field_line_test.sh path/to/loopwire}
source "$(dirname "$0")/../support/test_lib.sh"

pty="$WORK_DIR/ttyField"
# A pseudo-terminal applies no line settings: the three share it at the scan's 19200 8E1.
start_background sim.log "$loopwire" simulate --pty "$pty" --device tc10@3 --device ac20@7 --device rampsoak@5 --unit 9 \
  --duration 100s
wait_for_path "$pty"

config="$WORK_DIR/found.toml"
check scan-emits-config 0 "wrote $config" "$loopwire" scan --link "rtu:$pty" --units 1-10 --timeout 200ms --emit-config "$config"
[[ -f $config ]] || fail "scan --emit-config wrote no $config"
for device in tc10@3 ac20@7 rampsoak@5; do
    expect "config-has-$device" grep -q "^device = \"$device\"$" "$config"
done
expect config-names-devices grep -q '^name = "tc10-3"$' "$config"
expect config-has-the-scanned-link grep -q "^link = \"rtu:$pty?baud=19200&parity=even&data=8&stop=1\"$" "$config"
expect config-comments-the-unknown-unit grep -q '^# unit 9 answered but matches no profile' "$config"
expect config-has-no-device-for-unit-9 test "$(grep -c '@9"' "$config")" -eq 0
check emitted-config-passes-check 0 "" "$loopwire" gateway --config "$config" --check
# The unit that cannot be identified has no device table, and nothing else was found.
expect config-has-three-devices test "$(grep -c '^\[\[lines.devices\]\]$' "$config")" -eq 3

# Nothing identified, nothing written: a configuration without a device would not pass --check.
empty="$WORK_DIR/empty.toml"
check scan-writes-nothing-without-a-device 2 "nothing was written" \
  "$loopwire" scan --link "rtu:$pty" --units 9 --timeout 200ms --emit-config "$empty"
expect empty-config-not-written test ! -e "$empty"

# A unit without Read Device Identification (43/14) answers exception 01h: describe says so.
check describe-link-without-identification 0 "does not implement Read Device Identification" \
  "$loopwire" describe --link "rtu:$pty" --unit 9
check describe-link-refuses-broadcast 2 "not 0 (broadcast)" "$loopwire" describe --link "rtu:$pty" --unit 0
check describe-link-json-null 0 '{"unit":9,"device_identity":null}' "$loopwire" describe --link "rtu:$pty" --unit 9 --json

# RS-485 direction control on a port that has none.
check rs485-true-refused 3 "rs485=auto" "$loopwire" read --link "rtu:$pty?rs485=true" --unit 9 holding 0 1
check rs485-true-says-why 3 "TIOCSRS485" "$loopwire" read --link "rtu:$pty?rs485=1" --unit 9 holding 0 1
check rs485-auto-runs 0 "running without it" "$loopwire" read --link "rtu:$pty?rs485=auto&rs485_delay_before=1ms" --unit 9 holding 0 1
check guard-in-link-runs 0 "" "$loopwire" read --link "rtu:$pty?guard=3.5c" --unit 9 holding 0 1

# rs485 = true in a gateway's line on a port without kernel RS-485 control: --check refuses it,
# saying what to do; rs485 = "auto" passes.
sed "s|^link = \"rtu:$pty?\(.*\)\"$|link = \"rtu:$pty?\\1\"\nrs485 = true|" "$config" >"$WORK_DIR/rs485.toml"
expect rs485-config-written grep -q '^rs485 = true$' "$WORK_DIR/rs485.toml"
check rs485-true-refused-by-check 2 'rs485 = "auto"' "$loopwire" gateway --config "$WORK_DIR/rs485.toml" --check
check rs485-check-says-why 2 "TIOCGRS485" "$loopwire" gateway --config "$WORK_DIR/rs485.toml" --check
sed 's|^rs485 = true$|rs485 = "auto"|' "$WORK_DIR/rs485.toml" >"$WORK_DIR/rs485-auto.toml"
check rs485-auto-passes-check 0 "" "$loopwire" gateway --config "$WORK_DIR/rs485-auto.toml" --check

finish
