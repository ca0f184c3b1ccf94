#!/usr/bin/env bash
# The layer check must reject an app file that includes the session or transport layer, though
# both are below it, and accept the app's includes of client/ and simulation/.
set -euo pipefail
# shellcheck source=tests/support/test_lib.sh
source "$(dirname "$0")/../support/test_lib.sh"
check=$1
tree=$WORK_DIR/src
mkdir -p "$tree/app" "$tree/client"
printf '#include "client/link.hpp"\n#include "session/master.hpp"\n' > "$tree/app/bad_master.cpp"
printf '#include "transport/link_url.hpp"\n' > "$tree/app/bad_link.hpp"
printf '#include "client/link.hpp"\n#include "simulation/simulator_server.hpp"\n' > "$tree/app/good.cpp"
printf '#include "session/master.hpp"\n' > "$tree/client/link.hpp"
if out=$(/usr/bin/python3 "$check" "$tree"); then
  fail "an app include of session/ or transport/ was accepted: $out"
fi
grep -q "app/bad_master.cpp:2: layer 'app' includes 'session', which it must skip" <<<"$out" || fail "session include not reported: $out"
grep -q "app/bad_link.hpp:1: layer 'app' includes 'transport', which it must skip" <<<"$out" || fail "transport include not reported: $out"
if grep -q "good.cpp\|client/link.hpp" <<<"$out"; then fail "an allowed include was reported: $out"; fi
echo "ok: $out"
