#!/bin/bash
# mbpoll (an RTU master on libmodbus) drives a simulated controller over loopwire's --pty:
# identification word, a write read back, and an exception the manual names.
#
# Usage: simulators_vs_mbpoll.sh LOOPWIRE ac20|tc10|rampsoak
# The link is 8N1 (pseudo-terminals keep no parity, PEERS.md); mbpoll: `-0` wire addresses,
# `-1` one poll, always inside `timeout`.

set -euo pipefail
# shellcheck source=tests/support/test_lib.sh
source "$(dirname "$0")/../support/test_lib.sh"

readonly LOOPWIRE=$1 DEVICE_ID=$2
readonly UNIT=9

start_background simulate.log "$LOOPWIRE" simulate --link "rtu:/unused?baud=19200&parity=none" --pty "$WORK_DIR/tty" \
    --device "$DEVICE_ID@$UNIT" --duration "${PEER_LIFETIME}s" -v
wait_for_path "$WORK_DIR/tty"

mbpoll_run() {  # OPTIONS... [-- VALUES...] : one exchange (values after the port, as mbpoll wants them);
               # output in $WORK_DIR/mbpoll.out; mbpoll's exit status returned
    local options=() values=()
    while [[ $# -gt 0 && $1 != -- ]]; do options+=("$1"); shift; done
    [[ $# -gt 0 ]] && shift && values=("$@")
    timeout 10 mbpoll -m rtu -b 19200 -P none -a "$UNIT" -0 -1 -o 1 "${options[@]}" "$WORK_DIR/tty" "${values[@]}" \
        >"$WORK_DIR/mbpoll.out" 2>&1
}
mbpoll_ok() { mbpoll_run "$@" || fail "mbpoll $* exited $?: $(cat "$WORK_DIR/mbpoll.out")"; }
mbpoll_read() {  # ARGS... : the values mbpoll printed, space separated
    mbpoll_ok "$@"
    sed -nE 's/^\[[0-9]+\]:[[:space:]]+(-?[0-9]+).*/\1/p' "$WORK_DIR/mbpoll.out" | paste -sd ' '
}
mbpoll_refused() {  # TEXT ARGS... : mbpoll must fail with TEXT in its output (an exception reply)
    local text=$1
    shift
    if mbpoll_run "$@"; then fail "mbpoll $* succeeded; expected '$text'"; fi
    grep -qi "$text" "$WORK_DIR/mbpoll.out" || fail "mbpoll $*: expected '$text', got: $(cat "$WORK_DIR/mbpoll.out")"
    echo "ok: mbpoll $* -> $text"
}

case $DEVICE_ID in
    ac20)  # ac20-modbus-jbus-eng824e.en.txt: word 120 = 50; Note 5 remote before writes; error 9
        expect_equal "$(mbpoll_read -r 120)" "50" "AC20 word 120"
        mbpoll_ok -t 0 -r 218 -- 1
        mbpoll_ok -r 138 -- 42
        expect_equal "$(mbpoll_read -r 138)" "42" "AC20 main set point after the write in remote"
        # error 9 ("illegal number of data"): libmodbus has no text for exception 9 and prints its
        # errno, MODBUS_ENOBASE (112345678) + 9
        mbpoll_refused "112345687" -r 120 -c 21
        ;;
    tc10)  # tc10-modbus-im05c01e81-03.ru.txt: word 21 = 20; SP at both ranges; exception 3 above 16
        expect_equal "$(mbpoll_read -r 21)" "20" "TC10 word 21"
        mbpoll_ok -r 717 -- 123
        expect_equal "$(mbpoll_read -r 10317)" "123" "TC10 SP read at its second address"
        mbpoll_refused "Illegal data value" -r 640 -c 17
        ;;
    rampsoak)  # rampsoak-pid-rtu-ascii-linking.en.txt: SV at 0000H; read-only segment (exception 2)
        mbpoll_ok -r 0 -- 321
        expect_equal "$(mbpoll_read -r 0)" "321" "ramp/soak SV"
        mbpoll_refused "Illegal data address" -r 7 -- 5
        ;;
    *)
        fail "unknown device $DEVICE_ID"
        ;;
esac

grep -q "RX 09 " "$WORK_DIR/simulate.log" || fail "the simulator's trace shows no request"
echo PASS
