#!/usr/bin/env bash
# Names as people type them, through the CLI: the nearest names offered on a miss, ASCII for the
# AC20 manual's 'ñ', describe's groups and a wrong --group listing them, and a monitored NAME
# that matches nothing on one of several devices being an error.
set -u
loopwire=${1:?usage: names_test.sh path/to/loopwire}
source "$(dirname "$0")/../support/test_lib.sh"

start_background sim.log timeout 60 "$loopwire" simulate --pty "$WORK_DIR/ttyN" \
  --device tc10@3 --device rampsoak@5 --device ac20@1 --duration 50s
wait_for_text "$WORK_DIR/sim.log" "Ctrl-C to stop"
link="rtu:$WORK_DIR/ttyN?parity=none"

# A miss: exit 2, the nearest name with its mnemonic; nothing is sent (no link needed).
check miss-suggests 2 'no parameter "sett_point" on tc10; did you mean set_point (SP)?' \
  "$loopwire" read --link "$link" --device tc10@3 sett_point
check miss-suggests-on-write 2 'did you mean set_point (SP)?' "$loopwire" write --link "$link" --device tc10@3 sett_point=10
check miss-swapped-letters 2 'did you mean set_point_low_limit (SP.LL) or set_point_high_limit (SP.HL)?' \
  "$loopwire" read --link "$link" --device tc10@3 SP.LH
check miss-nothing-close 2 '`loopwire describe tc10` lists its names' "$loopwire" read --link "$link" --device tc10@3 qqqqqqqqqq
check miss-ascii-offers-manual-spelling 2 'did you mean main_output_low_limit (ñ.OLL)' \
  "$loopwire" read --link "$link" --device ac20@1 m.OLX

# ASCII for 'ñ': m.OLL is ñ.OLL, Alrm is the group Alrñ; the manual's spelling still works.
check ascii-mnemonic 0 '"main_output_low_limit"' "$loopwire" read --link "$link" --device ac20@1 m.OLL --json
check manual-mnemonic 0 '"main_output_low_limit"' "$loopwire" read --link "$link" --device ac20@1 ñ.OLL --json
check ascii-mnemonic-lower 0 'main_output_low_limit' "$loopwire" read --link "$link" --device ac20@1 M.oll
check ascii-group-read 0 '"alarm_1_threshold"' "$loopwire" read --link "$link" --device ac20@1 Alrm --json
check ascii-group-describe 0 'alarm_1_threshold' "$loopwire" describe ac20 --group alrm

# describe lists the groups; a wrong --group lists them too.
check describe-groups 0 'groups (--group G shows one): ' "$loopwire" describe tc10
check describe-group-counts 0 'SP (' "$loopwire" describe tc10
check describe-groups-json 0 '"groups":["' "$loopwire" describe tc10 --json
check describe-wrong-group 2 "tc10 has no group 'nope'; its groups: " "$loopwire" describe tc10 --group nope
check describe-wrong-group-lists 2 ', SP, ' "$loopwire" describe tc10 --group nope
check read-wrong-group 2 'its groups: ' "$loopwire" read --link "$link" --device tc10@3 group:nope

# Several monitored devices: a plain NAME must match on each.
check monitor-miss-on-one 2 'rampsoak@5: no parameter "output_power" on rampsoak' \
  "$loopwire" monitor --link "$link" --device tc10@3 --device rampsoak@5 output_power --count 1 --format csv
check monitor-miss-says-how 2 'write tc10@3:output_power' \
  "$loopwire" monitor --link "$link" --device tc10@3 --device rampsoak@5 output_power --count 1 --format csv
check monitor-miss-suggests 2 'did you mean' \
  "$loopwire" monitor --link "$link" --device tc10@3 --device rampsoak@5 set_pont --count 1 --format csv
check monitor-on-all 0 'tc10@3:output_power [%],rampsoak@5 status,rampsoak@5 errors,rampsoak@5:output_percentage [%]' \
  "$loopwire" monitor --link "$link" --device tc10@3 --device rampsoak@5 OUT --count 1 --format csv
check monitor-qualified 0 'tc10@3:output_power [%],rampsoak@5 status' \
  "$loopwire" monitor --link "$link" --device tc10@3 --device rampsoak@5 tc10@3:output_power --count 1 --format csv
finish
