#!/usr/bin/env bash
# bash completion as installed by `cmake --install`: the script is sourced into bash, the words
# of a command line are put in COMP_WORDS/COMP_CWORD as readline would, and the completion
# function must offer command names, each command's options, choices, device ids, files, and
# the parameter names of the device given with --device. Run twice: with the bare script, and
# with the bash-completion package's helpers loaded (as in an interactive shell), when present.
#   bash_completion_test.sh CMAKE BUILD_DIR
set -u
cmake=${1:?usage: bash_completion_test.sh CMAKE BUILD_DIR} build=${2:?}
source "$(dirname "$0")/../support/test_lib.sh"

prefix=$WORK_DIR/prefix
"$cmake" --install "$build" --prefix "$prefix" >"$WORK_DIR/install.log" 2>&1 || fail "cmake --install failed: $(cat "$WORK_DIR/install.log")"
script=$prefix/share/bash-completion/completions/loopwire
[[ -f $script ]] || fail "the bash completion script is not installed"
export PATH=$prefix/bin:$PATH
cd "$WORK_DIR" || fail "no work dir"
# A profile of the user's own, loaded with --profile: its id and parameters are completed too.
sed 's/"id": "tc10"/"id": "oven-x"/' "$(dirname "$0")/../../profiles/tc10.json" >"$WORK_DIR/oven-x.json"
touch "$WORK_DIR/plant.toml"

helpers=/usr/share/bash-completion/bash_completion
# completions LINE: what pressing TAB at the end of LINE offers, one a line, sorted.
completions() {
    bash -c '
        [[ $1 == with-helpers ]] && source "$2"
        source "$3"
        COMP_LINE=$4 COMP_POINT=${#4}
        read -r -a COMP_WORDS <<<"$4"
        [[ $4 == *" " ]] && COMP_WORDS+=("")
        COMP_CWORD=$((${#COMP_WORDS[@]} - 1))
        _loopwire loopwire "${COMP_WORDS[COMP_CWORD]}" "${COMP_WORDS[COMP_CWORD-1]}"
        printf "%s\n" "${COMPREPLY[@]}" | sort' _ "$mode" "$helpers" "$script" "$1"
}
# offers NAME LINE WORD...: TAB after LINE offers each WORD.
offers() {
    local name=$1 line=$2 word missing=() got
    shift 2
    got=$(completions "$line")
    for word in "$@"; do grep -qxF -- "$word" <<<"$got" || missing+=("$word"); done
    if ((${#missing[@]})); then
        echo "FAIL [$mode] $name: '$line<TAB>' lacks ${missing[*]}; offers: $(tr '\n' ' ' <<<"$got")"
        failures=$((failures + 1))
    else
        passes=$((passes + 1))
    fi
}
# offers_only NAME LINE WORD...: TAB after LINE offers exactly the WORDs.
offers_only() {
    local name=$1 line=$2 got want
    shift 2
    got=$(completions "$line")
    want=$(printf '%s\n' "$@" | sort)
    if [[ $got == "$want" ]]; then passes=$((passes + 1)); else
        echo "FAIL [$mode] $name: '$line<TAB>' offers $(tr '\n' ' ' <<<"$got"), want $(tr '\n' ' ' <<<"$want")"
        failures=$((failures + 1))
    fi
}

modes=(bare)
if [[ -f $helpers ]]; then modes+=(with-helpers); else echo "SKIP with-helpers: no bash-completion package ($helpers)"; fi
device_ids=$(loopwire devices --json | python3 -c 'import json,sys; print(" ".join(d["id"] + "@" for d in json.load(sys.stdin)))')
for mode in "${modes[@]}"; do
    echo "--- $mode"
    offers_only "command names" "loopwire re" read restore
    offers "every command" "loopwire " read write scan devices describe monitor dump restore simulate decode demo gateway
    offers_only "an option of read" "loopwire read --de" --device
    offers "parameter names of the device given with --device" "loopwire read --device tc10@3 s" set_point sp.ll set_point_low_limit
    offers "mnemonics in the case typed" "loopwire read --device tc10@3 SP" SP SP.LL SP.HL
    offers "names of each device, after other names" "loopwire monitor --device tc10@3 --device ac20@1 pv " all set_point
    offers_only "writable parameters as NAME=" "loopwire write --device tc10@3 set_point_l" set_point_low_limit=
    # shellcheck disable=SC2086  # one word per device id
    offers "device ids for --device" "loopwire read --device " $device_ids
    offers "device ids for describe" "loopwire describe t" tc10
    offers "a --profile file's device id" "loopwire read --profile $WORK_DIR/oven-x.json --device o" oven-x@
    offers "a --profile file's parameters" "loopwire read --profile $WORK_DIR/oven-x.json --device oven-x@1 set_point_h" set_point_high_limit
    offers_only "the choices of --protocol" "loopwire decode --protocol " ascii linking rtu tcp
    offers "files for --config" "loopwire gateway --config pl" plant.toml
    offers "files for --profile" "loopwire devices --profile oven" oven-x.json
    offers "groups for describe --group" "loopwire describe tc10 --group " "$(loopwire describe tc10 --json | python3 -c 'import json,sys; print(json.load(sys.stdin)["parameters"][0]["group"])')"
    offers_only "the tables of read" "loopwire read --link tcp://127.0.0.1:1502 --unit 1 " holding input coils discrete
    offers_only "the tables of write" "loopwire write --unit 1 " holding coils
    offers_only "the types of --type" "loopwire write --type " int16 uint16 int32 uint32 float32 float64 string
    offers_only "the word orders" "loopwire read --word-order " big little ABCD CDAB BADC DCBA
    offers_only "the formats of read" "loopwire read --format " dec hex bin
    offers_only "nothing that is not there" "loopwire read --device tc10@3 zzz"
done

# Every option a command's --help lists is completed: the scripts never drift from the commands.
mode=bare
for command in $(loopwire --help | awk '/^SUBCOMMANDS:|^Subcommands:/{f=1; next} f && /^  [a-z]/{print $1} f && /^$/{f=0}'); do
    # shellcheck disable=SC2046  # one word per option
    offers "every option of $command" "loopwire $command --" $(loopwire "$command" --help | grep -oE '^ +(-[a-zA-Z], ?)?--[a-z][a-z-]*' | grep -oE -- '--[a-z-]+$')
done
finish
