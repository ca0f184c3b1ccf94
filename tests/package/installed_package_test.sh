#!/usr/bin/env bash
# Installs the build into a temporary prefix, builds examples/ against the installed package
# with find_package(loopwire), and runs the example: the set point it writes must read back,
# with its unit, from the simulated TC10.
#   installed_package_test.sh CMAKE BUILD_DIR SOURCE_DIR GENERATOR CXX VERSION [LAUNCHER]
set -euo pipefail
cmake=$1 build=$2 source=$3 generator=$4 cxx=$5 version=$6 launcher=${7:-}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

fail() { echo "FAIL: $*" >&2; exit 1; }
run_logged() {  # log-name, command...: the command's output is shown only when it fails
    local log=$work/$1.log; shift
    "$@" >"$log" 2>&1 || { cat "$log" >&2; fail "$* exited with $?"; }
}

prefix=$work/prefix
run_logged install "$cmake" --install "$build" --prefix "$prefix"

for file in bin/loopwire include/loopwire/loopwire.hpp include/loopwire/version.hpp lib/libloopwire.a \
            lib/cmake/loopwire/loopwireConfig.cmake lib/cmake/loopwire/loopwireConfigVersion.cmake; do
    [ -e "$prefix/$file" ] || fail "$file is not installed under the prefix"
done
# The public headers stand alone: they include only <loopwire/...> and the standard library.
if grep -n '#include "' "$prefix"/include/loopwire/*.hpp; then fail "an installed header includes a private header"; fi
[ "$("$prefix/bin/loopwire" --version)" = "loopwire $version" ] || fail "installed loopwire --version does not say $version"

args=(-S "$source/examples" -B "$work/examples" -G "$generator" -DCMAKE_PREFIX_PATH="$prefix" -DCMAKE_CXX_COMPILER="$cxx")
[ -n "$launcher" ] && args+=(-DCMAKE_CXX_COMPILER_LAUNCHER="$launcher")
run_logged configure "$cmake" "${args[@]}"
run_logged build "$cmake" --build "$work/examples"

output=$("$work/examples/tc10_set_point" 123) || fail "the example failed: $output"
echo "$output"
grep -qx "loopwire $version" <<<"$output" || fail "the example does not print the installed version $version"
grep -q '^measured_value (rV) = -\?[0-9.]* °C$' <<<"$output" || fail "no measured value in °C"
# The unit from the device's unit word, the limits from its SP.LL and SP.HL words.
grep -A1 '^wrote set_point = 123$' <<<"$output" | grep -qx 'set_point (SP) = 123 °C (-\?[0-9.]* to [0-9.]*)' \
    || fail "the written set point 123 does not read back as '123 °C (LOW to HIGH)'"
echo "PASS: the installed package builds and runs the example"
