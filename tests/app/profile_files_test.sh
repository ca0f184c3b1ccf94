#!/usr/bin/env bash
# Profiles loaded at run time: a copy of profiles/tc10.json under the id "oven-x", named with
# --profile and then found in the user's profile folder, is described, simulated, read and
# written like a built-in device without rebuilding loopwire; bad files, clashing ids and
# unreadable folders say which file and what to do.
set -u
loopwire=${1:?usage: profile_files_test.sh path/to/loopwire}
loopwire_binary=$(cd "$(dirname "$loopwire")" && pwd)/$(basename "$loopwire")
source "$(dirname "$0")/../support/test_lib.sh"
python=/usr/bin/python3
profiles_dir="$(cd "$(dirname "$0")/../../profiles" && pwd)"

# tc10.json with another id (and optionally one broken value): a device with no model of its own.
make_profile() {  # id, output, [broken]
  $python - "$profiles_dir/tc10.json" "$1" "$2" "${3:-}" <<'PY'
import json, sys
document = json.load(open(sys.argv[1]))
document["id"] = sys.argv[2]
if sys.argv[4]:
    document["parameters"][0]["access"] = "sometimes"
json.dump(document, open(sys.argv[3], "w"), indent=2)
PY
}

# Every run gets its own configuration folder, so the user's own profiles never interfere.
empty_config="$WORK_DIR/empty-config"
mkdir -p "$empty_config"
folder_config="$WORK_DIR/config"
mkdir -p "$folder_config/loopwire/profiles"
make_profile oven-x "$WORK_DIR/oven-x.json"
make_profile oven-x "$folder_config/loopwire/profiles/oven-x.json"

# Serves oven-x@3 on a kernel-chosen loopback port; sets `link` to it. $@: the loopwire command.
start_simulator() {
  start_tcp_server "simulate.$RANDOM.log" "$@" simulate --link "tcp://127.0.0.1:0" --device oven-x@3 --duration 60s
  link="tcp://127.0.0.1:$PORT"
}

stop_simulator() { kill "$LAST_PID" 2>/dev/null; wait "$LAST_PID" 2>/dev/null; }

# The same journey for one way of making oven-x known. $1: label; the rest: the loopwire command.
device_journey() {
  local label=$1; shift
  check "$label-describe" 0 "oven-x — " "$@" describe oven-x
  check "$label-describe-group" 0 "SP.HL" "$@" describe oven-x --group SP
  check "$label-describe-json" 0 '"id":"oven-x"' "$@" describe oven-x --json
  start_simulator "$@" || return
  check "$label-read" 0 "set_point" "$@" read --link "$link" --device oven-x@3 measured_value set_point
  check "$label-read-json-names-device" 0 '"device":"oven-x"' "$@" read --link "$link" --device oven-x@3 measured_value --json
  check "$label-write" 0 "wrote set_point = 150" "$@" write --link "$link" --device oven-x@3 set_point=150
  check "$label-read-back" 0 "(raw 150)" "$@" read --link "$link" --device oven-x@3 set_point
  check "$label-dump" 0 '"set_point"' "$@" dump --link "$link" --device oven-x@3
  check "$label-monitor" 0 "set_point" "$@" monitor --link "$link" --device oven-x@3 set_point --count 1 --format csv
  stop_simulator
}

# 1. Named with --profile, before the subcommand (a global option) ...
device_journey flag env XDG_CONFIG_HOME="$empty_config" "$loopwire" --profile "$WORK_DIR/oven-x.json"
# ... and after it.
check flag-after-subcommand 0 "oven-x — " env XDG_CONFIG_HOME="$empty_config" "$loopwire" describe --profile "$WORK_DIR/oven-x.json" oven-x
check flag-devices-lists-file 0 "[$WORK_DIR/oven-x.json]" env XDG_CONFIG_HOME="$empty_config" "$loopwire" devices --profile "$WORK_DIR/oven-x.json"
check flag-devices-lists-builtin 0 "[built-in]" env XDG_CONFIG_HOME="$empty_config" "$loopwire" devices --profile "$WORK_DIR/oven-x.json"
check flag-devices-json-source 0 "\"source\":\"$WORK_DIR/oven-x.json\"" env XDG_CONFIG_HOME="$empty_config" "$loopwire" devices --json --profile "$WORK_DIR/oven-x.json"
check flag-not-given-unknown 2 'unknown device "oven-x"' env XDG_CONFIG_HOME="$empty_config" "$loopwire" describe oven-x

# 2. Found in $XDG_CONFIG_HOME/loopwire/profiles ...
device_journey folder env XDG_CONFIG_HOME="$folder_config" "$loopwire"
check folder-devices-lists-file 0 "[$folder_config/loopwire/profiles/oven-x.json]" env XDG_CONFIG_HOME="$folder_config" "$loopwire" devices
# ... or in ~/.config/loopwire/profiles when XDG_CONFIG_HOME is empty.
mkdir -p "$WORK_DIR/home/.config"
cp -r "$folder_config/loopwire" "$WORK_DIR/home/.config/"
check home-folder 0 "oven-x — " env XDG_CONFIG_HOME= HOME="$WORK_DIR/home" "$loopwire" describe oven-x

# Errors. A bad file named with --profile: exit 2, the file and the schema's complaint.
make_profile oven-bad "$WORK_DIR/oven-bad.json" broken
check flag-invalid-file 2 "$WORK_DIR/oven-bad.json: /parameters/0/access" \
  env XDG_CONFIG_HOME="$empty_config" "$loopwire" --profile "$WORK_DIR/oven-bad.json" describe tc10
check flag-missing-file 2 "$WORK_DIR/nowhere.json: cannot open profile" \
  env XDG_CONFIG_HOME="$empty_config" "$loopwire" read --link tcp://127.0.0.1:1 --device tc10@3 set_point --profile "$WORK_DIR/nowhere.json"

# A bad file in the folder: a warning naming it, the others still load, and its id says why.
mkdir -p "$WORK_DIR/mixed/loopwire/profiles"
cp "$WORK_DIR/oven-x.json" "$WORK_DIR/mixed/loopwire/profiles/"
cp "$WORK_DIR/oven-bad.json" "$WORK_DIR/mixed/loopwire/profiles/"
check folder-invalid-warns 0 "warning: $WORK_DIR/mixed/loopwire/profiles/oven-bad.json: /parameters/0/access" \
  env XDG_CONFIG_HOME="$WORK_DIR/mixed" "$loopwire" describe oven-x
check folder-invalid-others-load 0 "oven-x — " env XDG_CONFIG_HOME="$WORK_DIR/mixed" "$loopwire" describe oven-x
check folder-invalid-id-explained 2 "the file $WORK_DIR/mixed/loopwire/profiles/oven-bad.json that may define it is invalid" \
  env XDG_CONFIG_HOME="$WORK_DIR/mixed" "$loopwire" read --link tcp://127.0.0.1:1 --device oven-bad@3 set_point

# Two profiles with one id: an error naming both, whether the second is a file or a built-in.
check duplicate-files 2 "\"oven-x\" is defined twice, by $WORK_DIR/oven-x.json and by $folder_config/loopwire/profiles/oven-x.json" \
  env XDG_CONFIG_HOME="$folder_config" "$loopwire" --profile "$WORK_DIR/oven-x.json" devices
make_profile tc10 "$WORK_DIR/tc10-copy.json"
# The same file named twice, or given with --profile and found in the folder too, is loaded once.
check same-file-twice 0 "oven-x — " env XDG_CONFIG_HOME="$empty_config" "$loopwire" --profile "$WORK_DIR/oven-x.json" \
  --profile "$WORK_DIR/oven-x.json" describe oven-x
check folder-file-given-too 0 "oven-x — " env XDG_CONFIG_HOME="$folder_config" "$loopwire" \
  --profile "$folder_config/loopwire/profiles/oven-x.json" describe oven-x
check duplicate-builtin 2 "\"tc10\" is defined twice, by the built-in profile and by $WORK_DIR/tc10-copy.json" \
  env XDG_CONFIG_HOME="$empty_config" "$loopwire" describe tc10 --profile "$WORK_DIR/tc10-copy.json"

# A profile folder that cannot be read: a warning, and the built-ins still work.
mkdir -p "$WORK_DIR/blocked/loopwire"
touch "$WORK_DIR/blocked/loopwire/profiles"  # a file where the folder should be
check folder-unreadable-warns 0 "warning: cannot read the profile folder $WORK_DIR/blocked/loopwire/profiles" \
  env XDG_CONFIG_HOME="$WORK_DIR/blocked" "$loopwire" describe tc10
if [ "$(id -u)" -ne 0 ]; then  # root reads any folder, whatever its mode
  mkdir -p "$WORK_DIR/locked/loopwire/profiles"
  chmod 000 "$WORK_DIR/locked/loopwire/profiles"
  check folder-no-permission-warns 0 "warning: cannot read the profile folder $WORK_DIR/locked/loopwire/profiles" \
    env XDG_CONFIG_HOME="$WORK_DIR/locked" "$loopwire" describe tc10
  chmod 700 "$WORK_DIR/locked/loopwire/profiles"
fi

# docs/cli.md's "copy a built-in as a start" commands, as printed, in a home of the test's own
# (from the repository's top folder, where the README's commands are run).
readme_home="$WORK_DIR/readme-home"
mkdir -p "$readme_home"
(
  cd "$profiles_dir/.." || exit 1
  export HOME="$readme_home" XDG_CONFIG_HOME=
  loopwire() { "$loopwire_binary" "$@"; }
  mkdir -p ~/.config/loopwire/profiles
  sed 's/"id": "tc10"/"id": "oven-x"/' profiles/tc10.json >~/.config/loopwire/profiles/oven-x.json
  loopwire describe oven-x
) >"$WORK_DIR/readme.log" 2>&1
check readme-copy-of-a-builtin 0 "oven-x — " cat "$WORK_DIR/readme.log"

finish
