#!/usr/bin/env bash
# Files that fight back: dump outputs that are links, FIFOs and device nodes; dump and state
# files with values of the wrong JSON type or shape, nested too deep, FIFOs and directories; a state file that cannot be saved, at start
# and while serving; temporaries left by a killed save; a device whose decimals word is nonsense.
set -u
loopwire=${1:?usage: hostile_files_test.sh path/to/loopwire}
source "$(dirname "$0")/../support/test_lib.sh"
python=/usr/bin/python3

is_dump() { $python -c 'import json,sys; d=json.load(open(sys.argv[1])); assert d["format"] == "loopwire-dump"' "$1"; }

start_tcp_server sim.log "$loopwire" simulate --link tcp://127.0.0.1:0 --device tc10@3 --unit 1 --duration 110s
link="tcp://127.0.0.1:$PORT"

# 1. dump --output: a link is followed, a FIFO or device written into, nothing else replaced.
mkdir "$WORK_DIR/real"
ln -s real/tc10.json "$WORK_DIR/link.json"
check dump-through-link 0 "written to" "$loopwire" dump --link "$link" --device tc10@3 --output "$WORK_DIR/link.json"
expect dump-link-kept test -L "$WORK_DIR/link.json"
expect dump-link-target-written is_dump "$WORK_DIR/real/tc10.json"
expect dump-new-file-private-to-its-owner test "$(stat -c %a "$WORK_DIR/real/tc10.json")" = 600
chmod 644 "$WORK_DIR/real/tc10.json"
check dump-over-existing 0 "written to" "$loopwire" dump --link "$link" --device tc10@3 --output "$WORK_DIR/real/tc10.json"
expect dump-existing-keeps-its-mode test "$(stat -c %a "$WORK_DIR/real/tc10.json")" = 644
mkfifo "$WORK_DIR/fifo"
cat "$WORK_DIR/fifo" >"$WORK_DIR/from-fifo.json" &
reader=$!
check dump-into-fifo 0 "written to" "$loopwire" dump --link "$link" --device tc10@3 --output "$WORK_DIR/fifo"
expect dump-fifo-reader-got-the-dump wait "$reader"
expect dump-fifo-dump-is-whole is_dump "$WORK_DIR/from-fifo.json"
expect dump-fifo-kept test -p "$WORK_DIR/fifo"
if mknod "$WORK_DIR/null" c 1 3 2>/dev/null; then  # a private /dev/null: a regression cannot destroy the real one
  check dump-into-char-device 0 "written to" "$loopwire" dump --link "$link" --device tc10@3 --output "$WORK_DIR/null"
  expect dump-char-device-kept test -c "$WORK_DIR/null"
fi
"$loopwire" dump --link "$link" --device tc10@3 --output /dev/stdout 2>"$WORK_DIR/stdout.err" >"$WORK_DIR/via-stdout.json"
expect dump-to-dev-stdout is_dump "$WORK_DIR/via-stdout.json"
mkdir "$WORK_DIR/a-directory"
check dump-into-directory-refused 2 "is a directory" "$loopwire" dump --link "$link" --device tc10@3 --output "$WORK_DIR/a-directory"

# 2, 3. A dump whose values have the wrong type or shape: refused by JSON pointer, exit 2, never
# an abort (exit 134) and never "0 differences".
"$loopwire" dump --link "$link" --device tc10@3 --output "$WORK_DIR/good.json" 2>/dev/null
mutate() {  # python expression on d -> writes $WORK_DIR/bad.json
  $python -c "import json,sys; d=json.load(open(sys.argv[1])); $1; json.dump(d, open(sys.argv[2], 'w'))" "$WORK_DIR/good.json" "$WORK_DIR/bad.json"
}
restore_refuses() {  # name, python mutation, expected text
  mutate "$2"
  check "$1" 2 "$3" "$loopwire" restore --link "$link" --device tc10@3 "$WORK_DIR/bad.json" --dry-run
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
# Restore writes raw words: a text (and value) edited without its raw word would be lost without
# a word ("0 differences"); refused, naming the parameter and what to edit.
restore_refuses restore-edited-text 'd["parameters"]["set_point"].update(text="9999", value=9999)' \
  'at /parameters/set_point: its text "9999" is not what its raw word'
check restore-good-dump-still-reads 0 "between the device" "$loopwire" restore --link "$link" --device tc10@3 "$WORK_DIR/good.json" --dry-run

state_refuses() {  # name, file text, expected text
  printf '%s' "$2" >"$WORK_DIR/bad-state.json"
  cp "$WORK_DIR/bad-state.json" "$WORK_DIR/bad-state.orig"
  check "$1" 2 "$3" "$loopwire" simulate --pty "$WORK_DIR/ttyS" --device tc10@3 --state "$WORK_DIR/bad-state.json" --duration 1s
  expect "$1-untouched" cmp -s "$WORK_DIR/bad-state.json" "$WORK_DIR/bad-state.orig"
}
header='"format": "loopwire-simulator-state", "version": 1'
state_refuses state-format-number '{"format": 1, "version": 1, "units": {}}' 'at /format: expected "loopwire-simulator-state", found the number 1'
state_refuses state-version-string '{"format": "loopwire-simulator-state", "version": "1", "units": {}}' 'at /version: expected 1, found a string "1"'
state_refuses state-profile-number "{$header, \"units\": {\"3\": {\"profile\": 3, \"saved\": {}}}}" 'at /units/3/profile: expected a profile id as a string'
state_refuses state-saved-string "{$header, \"units\": {\"3\": {\"profile\": \"tc10\", \"saved\": {\"set_point\": \"150\"}}}}" \
  'at /units/3/saved/set_point: expected a raw word, an integer 0..65535, found a string "150"'
state_refuses state-saved-float "{$header, \"units\": {\"3\": {\"profile\": \"tc10\", \"saved\": {\"set_point\": 150.5}}}}" \
  'at /units/3/saved/set_point: expected a raw word'
state_refuses state-unit-key "{$header, \"units\": {\"three\": {\"profile\": \"tc10\", \"saved\": {}}}}" 'at /units/three: expected a unit id 1..255'

# 3b. Arrays nested 100 000 deep: refused before they are parsed, exit 2, in a dump, a state file,
# a profile named with --profile, and a profile in the folder (a warning; the others load). Saying
# what was found printed the value, which recursed once per level: a stack overflow, exit 139.
$python -c "print('[' * 100000 + ']' * 100000)" >"$WORK_DIR/deep.json"
deep="nests arrays and objects 100000 levels deep (at most 64)"
check restore-deep-dump 2 "$deep" "$loopwire" restore --link "$link" --device tc10@3 "$WORK_DIR/deep.json" --dry-run
state_refuses state-deep "$(cat "$WORK_DIR/deep.json")" "$deep"
check profile-deep 2 "$deep" "$loopwire" --profile "$WORK_DIR/deep.json" devices
mkdir -p "$WORK_DIR/xdg/loopwire/profiles" && cp "$WORK_DIR/deep.json" "$WORK_DIR/xdg/loopwire/profiles/"
check profile-folder-deep-warns 0 "$deep" env XDG_CONFIG_HOME="$WORK_DIR/xdg" "$loopwire" describe tc10
check profile-folder-deep-others-load 0 "Yokogawa TC10" env XDG_CONFIG_HOME="$WORK_DIR/xdg" "$loopwire" describe tc10

# 3c. A state file that is not a regular file is refused unopened: a FIFO would hold the start
# forever (nothing writes to it), a directory is not "not valid JSON". A dump may come through a
# pipe (restore /dev/stdin), but a directory is said to be one.
mkfifo "$WORK_DIR/state-fifo"
check state-fifo-refused 2 "is a FIFO (named pipe), not a regular file" \
  "$loopwire" simulate --pty "$WORK_DIR/ttyS" --device tc10@3 --state "$WORK_DIR/state-fifo" --duration 1s
check state-directory-refused 2 "is a directory" \
  "$loopwire" simulate --pty "$WORK_DIR/ttyS" --device tc10@3 --state "$WORK_DIR/a-directory" --duration 1s
check restore-directory-refused 2 "is a directory" "$loopwire" restore --link "$link" --device tc10@3 "$WORK_DIR/a-directory" --dry-run

# 4. A state file that cannot be saved is found at start, before anything is served. Root may
# write anywhere, so an unprivileged user tries the read-only folder.
mkdir "$WORK_DIR/readonly" && echo "{$header, \"units\": {}}" >"$WORK_DIR/readonly/state.json" && chmod 555 "$WORK_DIR/readonly"
as_user=()
if [ "$(id -u)" -eq 0 ]; then chmod 755 "$WORK_DIR"; as_user=(setpriv --reuid=65534 --regid=65534 --clear-groups); fi
check state-unwritable-at-start 2 "cannot write $WORK_DIR/readonly/state.json" \
  "${as_user[@]}" "$loopwire" simulate --link "tcp://127.0.0.1:0" --device tc10@3 --state "$WORK_DIR/readonly/state.json" --duration 5s
out=$(timeout 10 "${as_user[@]}" "$loopwire" simulate --link "tcp://127.0.0.1:0" --device tc10@3 --state "$WORK_DIR/readonly/state.json" --duration 1s 2>&1)
expect state-unwritable-serves-nothing test "${out/listening/}" = "$out"

# 5. Temporaries left by a save killed half-way are cleared at the next start; 4. a save that
# fails while serving is reported and retried, the simulator goes on serving.
mkdir "$WORK_DIR/st"
state="$WORK_DIR/st/state.json"
echo "{$header, \"units\": {}}" >"$state"
echo half >"$state.tmp-Xy12Z9"
echo keep >"$WORK_DIR/st/notes.tmp-Xy12Z9"
start_tcp_server state-sim.log "$loopwire" simulate --link tcp://127.0.0.1:0 --device tc10@3 --state "$state" --duration 60s
sim=$LAST_PID
sport=$PORT
expect stale-temporary-removed test ! -e "$state.tmp-Xy12Z9"
expect stale-temporary-reported grep -q "removed $state.tmp-Xy12Z9" "$WORK_DIR/state-sim.log"
expect other-files-kept test -e "$WORK_DIR/st/notes.tmp-Xy12Z9"
mv "$WORK_DIR/st" "$WORK_DIR/st-away"  # the folder vanishes: saves fail
check write-while-unsaveable 0 "wrote set_point = 150" "$loopwire" write --link "tcp://127.0.0.1:$sport" --device tc10@3 set_point=150
wait_for_text "$WORK_DIR/state-sim.log" "saving the state failed"
count_pass  # save-failure-reported
check still-serving-after-failed-save 0 "(raw 150)" "$loopwire" read --link "tcp://127.0.0.1:$sport" --device tc10@3 set_point
mv "$WORK_DIR/st-away" "$WORK_DIR/st"  # back: the retry saves
wait_for_text "$WORK_DIR/state-sim.log" "the state is saved again"
count_pass  # save-recovered
expect saved-after-recovery grep -q '"set_point": 150' "$state"
# Unsaved at the end: a last attempt, then an error and a non-zero exit, never a quiet stop.
mv "$WORK_DIR/st" "$WORK_DIR/st-away"
check write-before-stop 0 "wrote set_point = 160" "$loopwire" write --link "tcp://127.0.0.1:$sport" --device tc10@3 set_point=160
kill -TERM "$sim"
wait "$sim"; status=$?
expect unsaved-at-exit-is-an-error test "$status" -ne 0
expect unsaved-at-exit-says-so grep -q "NOT saved in the state file" "$WORK_DIR/state-sim.log"

# 7. A decimals word of 0xFFFF (AC20 word 300) leaves values undecodable, not the dump failed:
# a plain register bank stands in for the AC20 here.
check bank-decimals-ffff 0 "wrote" "$loopwire" write --link "$link" --unit 1 holding 300 0xFFFF
check dump-with-bad-decimals 0 "undecodable" "$loopwire" dump --link "$link" --device ac20@1 --output "$WORK_DIR/ac20.json"
expect dump-undecodable-entry $python -c '
import json, sys
p = json.load(open(sys.argv[1]))["parameters"]
sp = p["main_set_point"]
assert sp["status"] == "undecodable" and len(sp["raw"]) == 1 and sp["value"] is None and "primary_variable_decimals" in sp["error"], sp
assert p["primary_variable_decimals"]["raw"] == [65535], p["primary_variable_decimals"]
' "$WORK_DIR/ac20.json"
check restore-reads-undecodable-dump 0 "between the device" "$loopwire" restore --link "$link" --device ac20@1 "$WORK_DIR/ac20.json" --dry-run

finish
