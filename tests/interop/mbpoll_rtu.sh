#!/bin/bash
# mbpoll (an RTU master built on libmodbus) writes to `loopwire simulate` and reads back.
#
# Usage: mbpoll_rtu.sh LOOPWIRE socat|pty
#   socat: loopwire opens one end of a socat pty pair as a serial port (8N1 given in the link
#          URL), mbpoll the other end; proves loopwire's serial-port path.
#   pty:   loopwire makes the pseudo-terminal itself (`--pty`, whose default is RTU 19200 8E1)
#          and mbpoll opens it with its own default parity, even; proves the --pty path.
# mbpoll: `-0` for 0-based (wire) addresses, `-1` to poll once, and always inside `timeout`
# (see ../shared/PEERS.md beside the repository).

set -euo pipefail
# shellcheck source=tests/support/test_lib.sh
source "$(dirname "$0")/../support/test_lib.sh"

readonly LOOPWIRE=$1 MODE=$2
readonly UNIT=7

case $MODE in
    socat)
        socat_pair "$WORK_DIR/ttyA" "$WORK_DIR/ttyB"
        start_background simulate.log "$LOOPWIRE" simulate --link "rtu:$WORK_DIR/ttyA?baud=19200&parity=none" \
            --unit "$UNIT" --duration "${PEER_LIFETIME}s" -v
        DEVICE=$WORK_DIR/ttyB
        PARITY=(-P none)
        # Wait until loopwire has the port open; before that mbpoll's request would go nowhere.
        wait_for_log simulate.log '(simulating) unit' >/dev/null
        ;;
    pty)
        start_background simulate.log "$LOOPWIRE" simulate --pty "$WORK_DIR/tty" --unit "$UNIT" \
            --duration "${PEER_LIFETIME}s" -v
        DEVICE=$WORK_DIR/tty
        PARITY=()
        wait_for_path "$DEVICE"
        ;;
    *)
        echo "usage: $0 LOOPWIRE socat|pty" >&2
        exit 2
        ;;
esac

# mbpoll_run ARGS... : one mbpoll exchange with unit $UNIT; mbpoll's output in $WORK_DIR/mbpoll.out.
mbpoll_run() {
    timeout 10 mbpoll -m rtu -b 19200 "${PARITY[@]}" -a "$UNIT" -0 -1 "$@" >"$WORK_DIR/mbpoll.out" 2>&1 ||
        fail "mbpoll $* exited $?: $(cat "$WORK_DIR/mbpoll.out")"
}

# mbpoll_read ARGS... : the values mbpoll printed ("[100]: 	11" lines), space separated.
mbpoll_read() {
    mbpoll_run "$@"
    sed -nE 's/^\[[0-9]+\]:[[:space:]]+([0-9]+).*/\1/p' "$WORK_DIR/mbpoll.out" | paste -sd ' '
}

# Holding registers: FC16 (several values), FC6 (one value), FC3 back.
mbpoll_run -r 100 "$DEVICE" 11 22 33 32767
mbpoll_run -r 200 "$DEVICE" 65535
expect_equal "$(mbpoll_read -r 100 -c 4 "$DEVICE")" "11 22 33 32767" "holding 100..103 after FC16"
expect_equal "$(mbpoll_read -r 199 -c 3 "$DEVICE")" "0 65535 0" "holding 199..201 after FC6"

# Coils (-t 0): FC15 across a byte boundary, FC5, FC1 back.
mbpoll_run -t 0 -r 5 "$DEVICE" 1 0 1 1 0 0 1 1 1 0
mbpoll_run -t 0 -r 6 "$DEVICE" 1
expect_equal "$(mbpoll_read -t 0 -r 4 -c 12 "$DEVICE")" "0 1 1 1 1 0 0 1 1 1 0 0" "coils 4..15"

# Tables that nothing can write read zero: input registers (-t 3), discrete inputs (-t 1).
expect_equal "$(mbpoll_read -t 3 -r 100 -c 4 "$DEVICE")" "0 0 0 0" "input 100..103"
expect_equal "$(mbpoll_read -t 1 -r 5 -c 6 "$DEVICE")" "0 0 0 0 0 0" "discrete 5..10"

# Another unit id: loopwire must stay silent, mbpoll times out (exit 1).
if timeout 10 mbpoll -m rtu -b 19200 "${PARITY[@]}" -a $((UNIT + 1)) -o 0.3 -0 -1 -r 100 "$DEVICE" \
    >"$WORK_DIR/mbpoll.out" 2>&1; then
    fail "unit $((UNIT + 1)) is not simulated but mbpoll got an answer: $(cat "$WORK_DIR/mbpoll.out")"
fi
grep -q "timed out" "$WORK_DIR/mbpoll.out" || fail "mbpoll failed otherwise than by timeout: $(cat "$WORK_DIR/mbpoll.out")"
echo "ok: unit $((UNIT + 1)) got no reply"

# The function codes really were the ones meant: the simulator's trace shows each request.
for function in 10 06 03 0F 05 01 04 02; do
    grep -q "RX 07 $function " "$WORK_DIR/simulate.log" || fail "no function $function request in the simulator's trace"
done
echo "ok: the trace shows functions 16, 6, 3, 15, 5, 1, 4 and 2"
echo PASS
