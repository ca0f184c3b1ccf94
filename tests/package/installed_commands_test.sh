#!/usr/bin/env bash
# The installed commands as a user meets them: `cmake --install` into a temporary prefix puts
# the binary in bin/, a man page for the program and for every command in share/man/man1, the
# configuration file's page in share/man/man5, and
# the bash and zsh completion scripts where those shells look; the binary runs; every page
# renders without a warning (groff -ww, man --warnings) and documents every option the command's
# --help lists; the README's "Install" commands and the one scripts/setup prints work as written.
#   installed_commands_test.sh CMAKE BUILD_DIR SOURCE_DIR
set -u
cmake=${1:?usage: installed_commands_test.sh CMAKE BUILD_DIR SOURCE_DIR} build=${2:?} source=${3:?}
source "$(dirname "$0")/../support/test_lib.sh"

prefix=$WORK_DIR/prefix
"$cmake" --install "$build" --prefix "$prefix" >"$WORK_DIR/install.log" 2>&1 || fail "cmake --install failed: $(cat "$WORK_DIR/install.log")"
loopwire=$prefix/bin/loopwire
[[ -x $loopwire ]] || fail "bin/loopwire is not installed"
check "installed loopwire runs" 0 "loopwire " "$loopwire" --version
check "installed loopwire knows its devices" 0 "tc10" "$loopwire" devices

# The commands, as `loopwire --help` lists them (the lines under "Subcommands:").
mapfile -t commands < <("$loopwire" --help | awk '/^SUBCOMMANDS:|^Subcommands:/{f=1; next} f && /^  [a-z]/{print $1} f && /^$/{f=0}')
((${#commands[@]} >= 10)) || fail "found only ${#commands[@]} commands in loopwire --help: ${commands[*]}"
echo "commands: ${commands[*]}"

man1=$prefix/share/man/man1
expect "loopwire.1 is installed" test -f "$man1/loopwire.1"
for command in "${commands[@]}"; do
    expect "loopwire-$command.1 is installed" test -f "$man1/loopwire-$command.1"
done
# Only the commands people use have pages: none for the hidden ones the shell and the build use.
pages=$(find "$man1" -name 'loopwire*.1' | wc -l)
expect_equal "$pages" $((${#commands[@]} + 1)) "pages installed (one per command and loopwire.1)"

# Every page renders without a warning, has the sections it should, and lists every option.
for page in "$man1"/loopwire*.1; do
    name=$(basename "$page" .1)
    check "$name: groff -man -ww -z prints no warning" 0 "" bash -c '! groff -man -ww -z "$1" 2>&1 | grep .' _ "$page"
    check "$name: man --warnings prints no warning" 0 "" bash -c \
        'out=$(MANWIDTH=80 man --warnings -l "$1" 2>&1 >/dev/null); [[ -z $out ]] || { echo "$out"; false; }' _ "$page"
    MANWIDTH=200 man -l "$page" 2>/dev/null >"$WORK_DIR/$name.txt"  # plain text: not a terminal
    for section in NAME SYNOPSIS DESCRIPTION OPTIONS "SEE ALSO"; do
        expect "$name has $section" grep -qx "$section" "$WORK_DIR/$name.txt"
    done
done
for command in "${commands[@]}"; do
    for option in $("$loopwire" "$command" --help | grep -oE '^ +(-[a-zA-Z], ?)?--[a-z][a-z-]*' | grep -oE -- '--[a-z-]+$'); do
        expect "loopwire-$command(1) documents $option" grep -q -- "$option" "$WORK_DIR/loopwire-$command.txt"
    done
done
check "loopwire-read(1) shows the read examples of docs/cli.md" 0 "--device tc10@3 PV SP sp.ll" cat "$WORK_DIR/loopwire-read.txt"
check "loopwire-read(1) gives the exit statuses" 0 "EXIT STATUS" cat "$WORK_DIR/loopwire-read.txt"
check "loopwire(1) lists the read command" 0 "loopwire read" cat "$WORK_DIR/loopwire.txt"

# The configuration file's page, written from the same schema as `gateway --print-config`:
# every key that prints is described in the page's TABLES (not only in its EXAMPLE).
config_page=$prefix/share/man/man5/loopwire-gateway.toml.5
expect "loopwire-gateway.toml.5 is installed" test -f "$config_page"
check "loopwire-gateway.toml(5): groff -man -ww -z prints no warning" 0 "" bash -c '! groff -man -ww -z "$1" 2>&1 | grep .' _ "$config_page"
check "loopwire-gateway.toml(5): man --warnings prints no warning" 0 "" bash -c \
    'out=$(MANWIDTH=80 man --warnings -l "$1" 2>&1 >/dev/null); [[ -z $out ]] || { echo "$out"; false; }' _ "$config_page"
MANWIDTH=200 man -l "$config_page" 2>/dev/null | sed -n '/^TABLES/,/^EXAMPLE/p' >"$WORK_DIR/config-tables.txt"
mapfile -t config_keys < <("$loopwire" gateway --print-config | sed -nE 's/^(# )?([a-z_]+) = .*/\2/p' | sort -u)
((${#config_keys[@]} >= 40)) || fail "--print-config names only ${#config_keys[@]} keys: ${config_keys[*]}"
for key in "${config_keys[@]}"; do
    expect "loopwire-gateway.toml(5) describes $key" grep -qE "^ +$key = " "$WORK_DIR/config-tables.txt"
done
check "loopwire-gateway(1) points to the configuration's page" 0 "loopwire-gateway.toml(5)" cat "$WORK_DIR/loopwire-gateway.txt"

expect "bash completion is installed" test -f "$prefix/share/bash-completion/completions/loopwire"
expect "zsh completion is installed" test -f "$prefix/share/zsh/site-functions/_loopwire"
expect "the bash completion script parses" bash -n "$prefix/share/bash-completion/completions/loopwire"

# The README's "Install for development" block and the command scripts/setup prints, run as written from a
# checkout whose build/ is this build, for a user whose home is a scratch folder.
checkout=$WORK_DIR/checkout
mkdir -p "$checkout" && ln -s "$(realpath "$build")" "$checkout/build"
run_as_user() {  # NAME SCRIPT: runs SCRIPT in bash from the checkout with a fresh HOME
    local home=$WORK_DIR/home-$1
    mkdir -p "$home"
    (cd "$checkout" && HOME=$home PATH=/usr/local/bin:/usr/bin:/bin MANPAGER=cat timeout 60 bash -e -c "$2") \
        >"$WORK_DIR/$1.log" 2>&1 || { count_failure "$1: the commands failed" "$WORK_DIR/$1.log"; return; }
    count_pass
    expect "$1: bin/loopwire is in ~/.local" test -x "$home/.local/bin/loopwire"
    expect "$1: the man pages are in ~/.local" test -f "$home/.local/share/man/man1/loopwire-read.1"
}
readme_install=$(awk '/^## Install for development/{s=1; next} s && /^## /{s=0} s && /^```sh/{f=1; next} s && /^```/{f=0} s && f' "$source/README.md")
[[ -n $readme_install ]] || fail "the README has no sh block under '## Install for development'"
echo "README Install block:"; echo "$readme_install" | sed 's/^/    /'
run_as_user readme "$readme_install"
check "README: man finds loopwire-read from the PATH the README sets" 0 "loopwire-read" cat "$WORK_DIR/readme.log"

setup_install=$(grep -oE '^ *echo "  cmake --install [^#"]*' "$source/scripts/setup" | sed 's/^ *echo "  //')
[[ -n $setup_install ]] || fail "scripts/setup prints no 'cmake --install' command"
echo "scripts/setup prints: $setup_install"
run_as_user setup "$setup_install"
finish
