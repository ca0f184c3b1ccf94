#!/usr/bin/env bash
# zsh completion as installed by `cmake --install`: _loopwire must parse (zsh -n), and, autoloaded
# from share/zsh/site-functions as compinit would, offer for a command line what the command
# definitions and profiles say. compadd and _files are builtins of the completion system that
# only work inside a completion widget; here they are functions that print what they are given,
# so the test sees exactly what zsh would be asked to offer. Skipped (exit 77) without zsh.
# The scripts are installed under a scratch home's ~/.local and found through the `fpath` line
# the README gives for ~/.zshrc.
#   zsh_completion_test.sh CMAKE BUILD_DIR README
set -u
cmake=${1:?usage: zsh_completion_test.sh CMAKE BUILD_DIR README} build=${2:?} readme=${3:?}
source "$(dirname "$0")/../support/test_lib.sh"
command -v zsh >/dev/null || { echo "SKIP: zsh is not installed (scripts/setup installs it)"; exit 77; }

export HOME=$WORK_DIR/home
prefix=$HOME/.local
"$cmake" --install "$build" --prefix "$prefix" >"$WORK_DIR/install.log" 2>&1 || fail "cmake --install failed: $(cat "$WORK_DIR/install.log")"
functions=$prefix/share/zsh/site-functions
[[ -f $functions/_loopwire ]] || fail "_loopwire is not installed"
check "_loopwire parses" 0 "" zsh -n "$functions/_loopwire"
export PATH=$prefix/bin:$PATH
fpath_line=$(grep -oE '`fpath=\([^`]*\)`' "$readme" | tr -d '`')
[[ -n $fpath_line ]] || fail "the README gives no fpath=(...) line for ~/.zshrc"
echo "README: $fpath_line"

# completions LINE: the words _loopwire hands compadd for TAB at the end of LINE ("S:" before
# those added without a space after them), or "FILES" when it asks for file names.
completions() {
    zsh -f -c '
        eval "$1"
        autoload -Uz _loopwire
        compadd() {
            local suffix=
            while [[ $1 != -- ]]; do [[ $1 == -S ]] && { suffix=S:; shift; }; shift; done
            shift
            print -l -- ${@/#/$suffix}
        }
        _files() { print FILES }
        words=(${(z)2})
        [[ $2 == *" " ]] && words+=("")
        CURRENT=${#words}
        _loopwire' _ "$fpath_line" "$1" | sort
}
offers() {  # NAME LINE WORD...: TAB after LINE offers each WORD
    local name=$1 line=$2 word missing=() got
    shift 2
    got=$(completions "$line")
    for word in "$@"; do grep -qxF -- "$word" <<<"$got" || missing+=("$word"); done
    if ((${#missing[@]})); then
        echo "FAIL $name: '$line<TAB>' lacks ${missing[*]}; offers: $(tr '\n' ' ' <<<"$got")"
        failures=$((failures + 1))
    else
        passes=$((passes + 1))
    fi
}
offers "command names" "loopwire re" read restore
offers "an option of read" "loopwire read --de" --device
offers "parameter names of the device given with --device" "loopwire read --device tc10@3 s" set_point sp.ll
offers "device ids, the unit still to type" "loopwire read --device t" S:tc10@
offers "writable parameters as NAME=" "loopwire write --device tc10@3 set_point_l" S:set_point_low_limit=
offers "files for --config" "loopwire gateway --config " FILES
got=$(completions "loopwire read --device tc10@3 zzz")
expect_equal "$got" "" "candidates for a name no device has"
finish
