#!/usr/bin/env bash
# The layer check must reject a codec file that includes the session layer.
set -euo pipefail
# shellcheck source=tests/support/test_lib.sh
source "$(dirname "$0")/../support/test_lib.sh"
check=$1
tree=$WORK_DIR/src
mkdir -p "$tree/codec" "$tree/session"
printf '#include "session/master.hpp"\n' > "$tree/codec/bad.cpp"
printf '#include "codec/pdu.hpp"\n' > "$tree/session/good.cpp"
if out=$(/usr/bin/python3 "$check" "$tree"); then
  fail "an upward include was accepted: $out"
fi
grep -q "codec/bad.cpp:1: layer 'codec' includes 'session'" <<<"$out" || fail "unexpected report: $out"
if grep -q "good.cpp" <<<"$out"; then fail "a downward include was reported: $out"; fi
echo "ok: $out"
