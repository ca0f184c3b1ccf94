#!/usr/bin/env bash
# An AC20 switched off half-way through programming a configuration menu (its state kept by
# `simulate --state`) starts in a configuration error (AC20 manual, "List of error codes":
# 101-106): reads of process values are refused with the error, `dump` still saves every
# stored parameter and marks the refused live values, and `restore` of an earlier dump
# programs the menus right again, which ends the error.
set -u
loopwire=${1:?usage: error_condition_test.sh path/to/loopwire}
source "$(dirname "$0")/../support/test_lib.sh"
python=/usr/bin/python3

start() {  # log -> $link and $simulator, the simulator serving ac20@1 from $WORK_DIR/ac20-state.json
  start_tcp_server "$1" "$loopwire" simulate --link tcp://127.0.0.1:0 --device ac20@1 --state "$WORK_DIR/ac20-state.json" \
    --duration 90s
  simulator=$LAST_PID
  link="tcp://127.0.0.1:$PORT"
}

start sim.log
check good-dump 0 "written to" "$loopwire" dump --link "$link" --device ac20@1 --output "$WORK_DIR/good.json"
# Menu 6 (bar graph) programmed low above high, and the power cut before the menu is closed.
check program-half 0 "wrote" "$loopwire" write --link "$link" --device ac20@1 local_remote=remote \
  configuration_mode_code=0 bar_graph_low=1.50 bar_graph_high=1.00
# The state file follows a change within a quarter second.
wait_for 5 "the half-programmed menu in the state file" grep -q '"bar_graph_low": 150' "$WORK_DIR/ac20-state.json"
kill "$simulator"; wait "$simulator" 2>/dev/null
start sim-restarted.log

check process-value-refused 5 "Error on configuration group 1" "$loopwire" read --link "$link" --device ac20@1 carbon_potential
check configuration-still-answers 0 "1.50 %C" "$loopwire" read --link "$link" --device ac20@1 bar_graph_low
check dump-in-error 0 "refused" "$loopwire" dump --link "$link" --device ac20@1 --output "$WORK_DIR/error.json"
if $python - "$WORK_DIR/error.json" <<'PY' >"$WORK_DIR/why" 2>&1
import json, sys
p = json.load(open(sys.argv[1]))["parameters"]
assert p["carbon_potential"]["status"] == "unread" and p["carbon_potential"]["value"] is None, p["carbon_potential"]
assert "101" in p["carbon_potential"]["error"], p["carbon_potential"]
assert p["bar_graph_low"]["value"] == 1.5 and p["bar_graph_high"]["value"] == 1.0, (p["bar_graph_low"], p["bar_graph_high"])
PY
then passes=$((passes + 1)); else echo "FAIL dump-in-error-content"; sed 's/^/    /' "$WORK_DIR/why"; failures=$((failures + 1)); fi

# Its identification words are refused too, so restore asks for --force before it writes.
check restore-needs-force 2 "add --force" "$loopwire" restore --link "$link" --device ac20@1 "$WORK_DIR/good.json" --yes
check restore-repairs 0 "restored" "$loopwire" restore --link "$link" --device ac20@1 "$WORK_DIR/good.json" --yes --force
check process-value-back 0 "carbon_potential" "$loopwire" read --link "$link" --device ac20@1 carbon_potential
finish
