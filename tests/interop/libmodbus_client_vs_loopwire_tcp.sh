#!/bin/bash
# A libmodbus Modbus/TCP master drives `loopwire simulate --link tcp://...`.
#
# Usage: libmodbus_client_vs_loopwire_tcp.sh LOOPWIRE LIBMODBUS_TCP_CLIENT
# The client's scenario writes and reads back with every write function (it exits non-zero on
# the first mismatch); afterwards loopwire's own master reads the same values over a second
# connection, which shows the simulator keeps state across connections.

set -euo pipefail
# shellcheck source=tests/support/test_lib.sh
source "$(dirname "$0")/../support/test_lib.sh"

readonly LOOPWIRE=$1 CLIENT=$2

# Port 0: loopwire takes a free port from the kernel and names it on stderr.
start_tcp_server simulate.log "$LOOPWIRE" simulate --link tcp://127.0.0.1:0 --unit 1 --duration "${PEER_LIFETIME}s"

timeout 20 "$CLIENT" 127.0.0.1 "$PORT" 1 scenario || fail "the libmodbus client's scenario failed (exit $?)"

readback=$(timeout 10 "$LOOPWIRE" read --link "tcp://127.0.0.1:$PORT" --unit 1 --timeout 1s holding 1009 3 --json) ||
    fail "loopwire read failed"
# Register 1009 was written by FC16 as (9 * 40503) & 0xFFFF, 1010 by FC6 as 0xBEEF, 1011 by
# FC16 as (11 * 40503) & 0xFFFF (see libmodbus_tcp_client.cpp).
expect_equal "$readback" \
    "{\"unit\":1,\"table\":\"holding\",\"address\":1009,\"values\":[$(((9 * 40503) & 0xFFFF)),48879,$(((11 * 40503) & 0xFFFF))]}" \
    "loopwire reads what libmodbus wrote"
echo PASS
