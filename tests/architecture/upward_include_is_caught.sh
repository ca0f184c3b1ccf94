#!/usr/bin/env bash
# The layer check must reject a codec file that includes the session layer.
set -euo pipefail
check=$1
tree=$(mktemp -d)
trap 'rm -rf "$tree"' EXIT
mkdir -p "$tree/codec" "$tree/session"
printf '#include "session/master.hpp"\n' > "$tree/codec/bad.cpp"
printf '#include "codec/pdu.hpp"\n' > "$tree/session/good.cpp"
if out=$(/usr/bin/python3 "$check" "$tree"); then
  echo "FAIL: an upward include was accepted: $out"; exit 1
fi
grep -q "codec/bad.cpp:1: layer 'codec' includes 'session'" <<<"$out" || { echo "FAIL: unexpected report: $out"; exit 1; }
grep -q "good.cpp" <<<"$out" && { echo "FAIL: a downward include was reported: $out"; exit 1; }
echo "ok: $out"
