#!/usr/bin/env bash
# Files that fight back: dump outputs that are links, FIFOs and device nodes; dump and state
# files with values of the wrong JSON type or shape; a state file that cannot be saved, at start
# and while serving; temporaries left by a killed save; a device whose decimals word is nonsense.
set -u
loopwire=${1:?usage: hostile_files_test.sh path/to/loopwire}
source "$(dirname "$0")/cli_test_lib.sh"
python=/usr/bin/python3

wait_for_text() {  # file, text: true once the file holds the text (5 s at most)
  for _ in $(seq 100); do grep -qF -- "$2" "$1" 2>/dev/null && return 0; sleep 0.05; done
  echo "    (waited 5 s for '$2' in $1)"; return 1
}
expect() {  # name, command...: passes when the command succeeds
  local name=$1; shift
  if "$@"; then passes=$((passes + 1)); else echo "FAIL $name"; failures=$((failures + 1)); fi
}
free_port() { $python -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])'; }
is_dump() { $python -c 'import json,sys; d=json.load(open(sys.argv[1])); assert d["format"] == "loopwire-dump"' "$1"; }

port=$(free_port)
"$loopwire" simulate --link "tcp://127.0.0.1:$port" --device tc10@3 --unit 1 --duration 110s 2>"$work/sim.log" &
pids+=($!)
wait_for_text "$work/sim.log" listening || { cat "$work/sim.log"; exit 1; }
link="tcp://127.0.0.1:$port"

# 1. dump --output: a link is followed, a FIFO or device written into, nothing else replaced.
mkdir "$work/real"
ln -s real/tc10.json "$work/link.json"
check dump-through-link 0 "written to" "$loopwire" dump --link "$link" --device tc10@3 --output "$work/link.json"
expect dump-link-kept test -L "$work/link.json"
expect dump-link-target-written is_dump "$work/real/tc10.json"
expect dump-new-file-private-to-its-owner test "$(stat -c %a "$work/real/tc10.json")" = 600
chmod 644 "$work/real/tc10.json"
check dump-over-existing 0 "written to" "$loopwire" dump --link "$link" --device tc10@3 --output "$work/real/tc10.json"
expect dump-existing-keeps-its-mode test "$(stat -c %a "$work/real/tc10.json")" = 644
mkfifo "$work/fifo"
cat "$work/fifo" >"$work/from-fifo.json" &
reader=$!
check dump-into-fifo 0 "written to" "$loopwire" dump --link "$link" --device tc10@3 --output "$work/fifo"
expect dump-fifo-reader-got-the-dump wait "$reader"
expect dump-fifo-dump-is-whole is_dump "$work/from-fifo.json"
expect dump-fifo-kept test -p "$work/fifo"
if mknod "$work/null" c 1 3 2>/dev/null; then  # a private /dev/null: a regression cannot destroy the real one
  check dump-into-char-device 0 "written to" "$loopwire" dump --link "$link" --device tc10@3 --output "$work/null"
  expect dump-char-device-kept test -c "$work/null"
fi
"$loopwire" dump --link "$link" --device tc10@3 --output /dev/stdout 2>"$work/stdout.err" >"$work/via-stdout.json"
expect dump-to-dev-stdout is_dump "$work/via-stdout.json"
mkdir "$work/a-directory"
check dump-into-directory-refused 2 "is a directory" "$loopwire" dump --link "$link" --device tc10@3 --output "$work/a-directory"

# 2, 3. A dump whose values have the wrong type or shape: refused by JSON pointer, exit 2, never
# an abort (exit 134) and never "0 differences".
"$loopwire" dump --link "$link" --device tc10@3 --output "$work/good.json" 2>/dev/null
mutate() {  # python expression on d -> writes $work/bad.json
  $python -c "import json,sys; d=json.load(open(sys.argv[1])); $1; json.dump(d, open(sys.argv[2], 'w'))" "$work/good.json" "$work/bad.json"
}
restore_refuses() {  # name, python mutation, expected text
  mutate "$2"
  check "$1" 2 "$3" "$loopwire" restore --link "$link" --device tc10@3 "$work/bad.json" --dry-run
}
restore_refuses restore-format-number 'd["format"] = 5' 'at /format: expected "loopwire-dump", found the number 5'
restore_refuses restore-version-string 'd["version"] = "1"' 'at /version: expected 1, found a string "1"'
restore_refuses restore-unit-string 'd["unit"] = "3"' 'at /unit: expected the unit id, an integer 0..255, found a string "3"'
restore_refuses restore-time-number 'd["time"] = 5' 'at /time: expected a string, found the number 5'
restore_refuses restore-profile-number 'd["profile"] = 7' 'at /profile: expected the profile id as a string'
restore_refuses restore-parameters-array 'd["parameters"] = []' 'at /parameters: expected an object of parameters by name'
restore_refuses restore-raw-float 'd["parameters"]["set_point"]["raw"] = [150.0]' \
  'at /parameters/set_point/raw: expected parameter set_point: one raw word, an integer 0..65535 in a list like [150], found an array [150.0]'
restore_refuses restore-raw-negative 'd["parameters"]["set_point"]["raw"] = [-1]' 'at /parameters/set_point/raw: expected parameter set_point'
restore_refuses restore-raw-fraction 'd["parameters"]["set_point"]["raw"] = [1.5]' 'found an array [1.5]'
restore_refuses restore-raw-two-words 'd["parameters"]["set_point"]["raw"] = [1, 2]' 'parameter set_point: expected one raw word, an integer 0..65535 in a list like [150], found 2 words'
restore_refuses restore-raw-none-but-ok 'd["parameters"]["set_point"]["raw"] = []' 'only an "unread" parameter has none'
restore_refuses restore-identification-string 'd["identification"] = {k: str(v) for k, v in d["identification"].items()}' 'at /identification/'
check restore-good-dump-still-reads 0 "differences between" "$loopwire" restore --link "$link" --device tc10@3 "$work/good.json" --dry-run

state_refuses() {  # name, file text, expected text
  printf '%s' "$2" >"$work/bad-state.json"
  cp "$work/bad-state.json" "$work/bad-state.orig"
  check "$1" 2 "$3" "$loopwire" simulate --pty "$work/ttyS" --device tc10@3 --state "$work/bad-state.json" --duration 1s
  expect "$1-untouched" cmp -s "$work/bad-state.json" "$work/bad-state.orig"
}
header='"format": "loopwire-simulator-state", "version": 1'
state_refuses state-format-number '{"format": 1, "version": 1, "units": {}}' 'at /format: expected "loopwire-simulator-state", found the number 1'
state_refuses state-version-string '{"format": "loopwire-simulator-state", "version": "1", "units": {}}' 'at /version: expected 1, found a string "1"'
state_refuses state-profile-number "{$header, \"units\": {\"3\": {\"profile\": 3, \"saved\": {}}}}" 'at /units/3/profile: expected a profile id as a string'
state_refuses state-saved-string "{$header, \"units\": {\"3\": {\"profile\": \"tc10\", \"saved\": {\"set_point\": \"150\"}}}}" \
  'at /units/3/saved/set_point: expected a raw word, an integer 0..65535, found a string "150"'
state_refuses state-saved-float "{$header, \"units\": {\"3\": {\"profile\": \"tc10\", \"saved\": {\"set_point\": 150.5}}}}" \
  'at /units/3/saved/set_point: expected a raw word'
state_refuses state-unit-key "{$header, \"units\": {\"three\": {\"profile\": \"tc10\", \"saved\": {}}}}" 'at /units/three: expected a unit id 1..247'

# 4. A state file that cannot be saved is found at start, before anything is served. Root may
# write anywhere, so an unprivileged user tries the read-only folder.
mkdir "$work/readonly" && echo "{$header, \"units\": {}}" >"$work/readonly/state.json" && chmod 555 "$work/readonly"
as_user=()
if [ "$(id -u)" -eq 0 ]; then chmod 755 "$work"; as_user=(setpriv --reuid=65534 --regid=65534 --clear-groups); fi
check state-unwritable-at-start 2 "cannot write $work/readonly/state.json" \
  "${as_user[@]}" "$loopwire" simulate --link "tcp://127.0.0.1:0" --device tc10@3 --state "$work/readonly/state.json" --duration 5s
out=$(timeout 10 "${as_user[@]}" "$loopwire" simulate --link "tcp://127.0.0.1:0" --device tc10@3 --state "$work/readonly/state.json" --duration 1s 2>&1)
expect state-unwritable-serves-nothing test "${out/listening/}" = "$out"

# 5. Temporaries left by a save killed half-way are cleared at the next start; 4. a save that
# fails while serving is reported and retried, the simulator goes on serving.
mkdir "$work/st"
state="$work/st/state.json"
echo "{$header, \"units\": {}}" >"$state"
echo half >"$state.tmp-Xy12Z9"
echo keep >"$work/st/notes.tmp-Xy12Z9"
sport=$(free_port)
"$loopwire" simulate --link "tcp://127.0.0.1:$sport" --device tc10@3 --state "$state" --duration 60s 2>"$work/state-sim.log" &
sim=$!
pids+=($sim)
expect state-sim-started wait_for_text "$work/state-sim.log" listening
expect stale-temporary-removed test ! -e "$state.tmp-Xy12Z9"
expect stale-temporary-reported grep -q "removed $state.tmp-Xy12Z9" "$work/state-sim.log"
expect other-files-kept test -e "$work/st/notes.tmp-Xy12Z9"
mv "$work/st" "$work/st-away"  # the folder vanishes: saves fail
check write-while-unsaveable 0 "wrote set_point = 150" "$loopwire" write --link "tcp://127.0.0.1:$sport" --device tc10@3 set_point=150
expect save-failure-reported wait_for_text "$work/state-sim.log" "saving the state failed"
check still-serving-after-failed-save 0 "(raw 150)" "$loopwire" read --link "tcp://127.0.0.1:$sport" --device tc10@3 set_point
mv "$work/st-away" "$work/st"  # back: the retry saves
expect save-recovered wait_for_text "$work/state-sim.log" "the state is saved again"
expect saved-after-recovery grep -q '"set_point": 150' "$state"
# Unsaved at the end: a last attempt, then an error and a non-zero exit, never a quiet stop.
mv "$work/st" "$work/st-away"
check write-before-stop 0 "wrote set_point = 160" "$loopwire" write --link "tcp://127.0.0.1:$sport" --device tc10@3 set_point=160
kill -TERM "$sim"
wait "$sim"; status=$?
expect unsaved-at-exit-is-an-error test "$status" -ne 0
expect unsaved-at-exit-says-so grep -q "NOT saved in the state file" "$work/state-sim.log"

# 7. A decimals word of 0xFFFF (AC20 word 300) leaves values undecodable, not the dump failed:
# a plain register bank stands in for the AC20 here.
check bank-decimals-ffff 0 "wrote" "$loopwire" write --link "$link" --unit 1 holding 300 0xFFFF
check dump-with-bad-decimals 0 "undecodable" "$loopwire" dump --link "$link" --device ac20@1 --output "$work/ac20.json"
expect dump-undecodable-entry $python -c '
import json, sys
p = json.load(open(sys.argv[1]))["parameters"]
sp = p["main_set_point"]
assert sp["status"] == "undecodable" and len(sp["raw"]) == 1 and sp["value"] is None and "primary_variable_decimals" in sp["error"], sp
assert p["primary_variable_decimals"]["raw"] == [65535], p["primary_variable_decimals"]
' "$work/ac20.json"
check restore-reads-undecodable-dump 0 "differences between" "$loopwire" restore --link "$link" --device ac20@1 "$work/ac20.json" --dry-run

finish
