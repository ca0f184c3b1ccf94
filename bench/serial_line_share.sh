#!/bin/bash
# One 19200-baud line, alone and shared: what ten Modbus TCP clients get through the gateway
# against what one master gets with the line to itself, on a line that keeps a real line's timing.
#
# The line is tests/support/paced_relay.py between `loopwire simulate` (a TC10, unit 3) and the
# master: bytes one character time apart (10 bits a character, 8N1: 1/1920 s), each write up to
# JITTER_MS late (2 ms: a busy host's or a USB adapter's lateness; never a silence inside a frame
# longer than that), no duplicates. Every request reads the same 16 holding registers (FC3,
# addresses 1-16), the TC10's most at once, and is sent as soon as the one before it ended.
#
# a. a plain RTU master alone on the line (bench/libmodbus_rtu_loop: libmodbus, which takes a
#    reply as whole once the bytes its function code calls for have come, then the 3.5
#    characters of silence before the next request): what the line gives a master that keeps
#    the rules and loses no time of its own, the reference;
# b. loopwire's own serial master alone on the line (bench/serial_master_loop: the gateway's
#    master, carried on the same kind of loop, without the gateway around it);
# c. ten libmodbus clients (gateway_throughput_client) through `loopwire gateway`, whose line is
#    the same relay.
# Printed: requests/s of each, the ratios c/a (the line shared through the gateway against a
# plain master alone: 0.95 or more is the goal) and c/b (the gateway against its own master),
# the garbled frames loopwire's masters counted (runs of bytes discarded: MasterOptions::discarded,
# the gateway's "garbled frame(s)"; from timing alone there should be none), the requests that
# failed, and the longest silence the relay really left inside a frame (on a loaded machine its
# own wake-ups come late too: a longer one than the jitter is the machine's, not the master's).
#
# Usage: bench/serial_line_share.sh BUILD_DIR [SECONDS] [JITTER_MS]   (SECONDS per figure, default 20)
# Builds nothing: BUILD_DIR must hold loopwire, bench/libmodbus_rtu_loop, bench/serial_master_loop
# and bench/gateway_throughput_client.
set -euo pipefail

if [[ $# -lt 1 || $# -gt 3 ]]; then
    echo "usage: $0 BUILD_DIR [SECONDS] [JITTER_MS]" >&2
    exit 2
fi
readonly BUILD_DIR=$1 DURATION=${2:-20} JITTER_MS=${3:-2}
readonly LOOPWIRE=$BUILD_DIR/loopwire
readonly PLAIN=$BUILD_DIR/bench/libmodbus_rtu_loop
readonly MASTER=$BUILD_DIR/bench/serial_master_loop
readonly CLIENT=$BUILD_DIR/bench/gateway_throughput_client
RELAY=$(dirname "$0")/../tests/support/paced_relay.py
readonly RELAY
for program in "$LOOPWIRE" "$PLAIN" "$MASTER" "$CLIENT"; do
    [[ -x $program ]] || { echo "$0: $program is missing: build it first (cmake --build $BUILD_DIR)" >&2; exit 2; }
done
[[ $DURATION =~ ^[1-9][0-9]*$ ]] || { echo "$0: SECONDS must be a positive whole number, not '$DURATION'" >&2; exit 2; }
[[ $JITTER_MS =~ ^[0-9]+(\.[0-9]+)?$ ]] || { echo "$0: JITTER_MS must be a number of milliseconds, not '$JITTER_MS'" >&2; exit 2; }

# shellcheck source=tests/support/test_lib.sh
source "$(dirname "$0")/../tests/support/test_lib.sh"

readonly CLIENTS=10 UNIT=3 ADDRESS=1 REGISTERS=16 BAUD=19200
# Background processes outlive the measurements only by this much (test_lib.sh: CTest's timeout
# kills with SIGKILL, which runs no trap).
readonly LIFETIME=$((3 * DURATION + 120))
readonly DEVICE_LINK=$WORK_DIR/ttyDevice MASTER_LINK=$WORK_DIR/ttyMaster
readonly LINK="rtu:$MASTER_LINK?baud=$BAUD&parity=none"

calc() { awk "BEGIN { printf \"$1\", $2 }"; }

# The relay at real-time priority if the machine grants it (it stands for a UART, which a busy
# host does not delay; its ready line says what it got).
start_background relay.log /usr/bin/python3 "$RELAY" --device-link "$DEVICE_LINK" --master-link "$MASTER_LINK" \
    --baud "$BAUD" --jitter-ms "$JITTER_MS" --realtime --lifetime "$LIFETIME"
RELAY_PID=$LAST_PID
wait_for_text "$WORK_DIR/relay.log" "paced_relay: ready"
start_background simulate.log "$LOOPWIRE" simulate --link "rtu:$DEVICE_LINK?baud=$BAUD&parity=none" \
    --device "tc10@$UNIT" --duration "${LIFETIME}s"

# --- a. A plain master alone ---
timeout $((DURATION + 60)) "$PLAIN" "$MASTER_LINK" "$BAUD" "$DURATION" "$UNIT" "$ADDRESS" "$REGISTERS" >"$WORK_DIR/plain.out" 2>&1 ||
    fail "the plain master failed: $(cat "$WORK_DIR/plain.out")"
plain_rate=$(sed -nE 's/^requests\/s: ([0-9.]+)$/\1/p' "$WORK_DIR/plain.out")
plain_failed=$(sed -nE 's/^requests: [0-9]+, failed: ([0-9]+),.*/\1/p' "$WORK_DIR/plain.out")
[[ -n $plain_rate && -n $plain_failed ]] || fail "the plain master printed no figures: $(cat "$WORK_DIR/plain.out")"

# --- b. loopwire's master alone ---
timeout $((DURATION + 60)) "$MASTER" "$LINK" "$DURATION" "$UNIT" "$ADDRESS" "$REGISTERS" >"$WORK_DIR/alone.out" 2>&1 ||
    fail "the master alone failed: $(cat "$WORK_DIR/alone.out")"
alone_rate=$(sed -nE 's/^requests\/s: ([0-9.]+)$/\1/p' "$WORK_DIR/alone.out")
alone_failed=$(sed -nE 's/^requests: [0-9]+, failed: ([0-9]+),.*/\1/p' "$WORK_DIR/alone.out")
alone_garbled=$(sed -nE 's/^garbled frames: ([0-9]+)$/\1/p' "$WORK_DIR/alone.out")
[[ -n $alone_rate && -n $alone_failed && -n $alone_garbled ]] || fail "the master alone printed no figures: $(cat "$WORK_DIR/alone.out")"

# --- c. Ten clients through the gateway ---
cat >"$WORK_DIR/gateway.toml" <<EOF
[[lines]]
name = "bench"
link = "$LINK"
timeout = "1s"

[[lines.devices]]
name = "tc10"
device = "tc10@$UNIT"
poll = "60m"
parameters = ["measured_value"]

[modbus_tcp]
listen = "127.0.0.1:0"
EOF
start_tcp_server gateway.log timeout "$LIFETIME" "$LOOPWIRE" gateway --config "$WORK_DIR/gateway.toml"
gateway_pid=$LAST_PID
# shellcheck disable=SC2153  # PORT is set by start_tcp_server (test_lib.sh)
timeout $((DURATION + 60)) "$CLIENT" 127.0.0.1 "$PORT" "$DURATION" "$CLIENTS" "$UNIT" "$ADDRESS" "$REGISTERS" count-failures \
    >"$WORK_DIR/shared.out" 2>&1 || fail "the clients failed: $(cat "$WORK_DIR/shared.out")"
shared_rate=$(sed -nE 's/^requests\/s: ([0-9.]+)$/\1/p' "$WORK_DIR/shared.out")
shared_failed=$(sed -nE 's/^requests failed: ([0-9]+)$/\1/p' "$WORK_DIR/shared.out")
shared_details=$(grep -E '^requests: ' "$WORK_DIR/shared.out")
[[ -n $shared_rate && -n $shared_failed ]] || fail "the clients printed no rate: $(cat "$WORK_DIR/shared.out")"
kill "$gateway_pid" 2>/dev/null || true  # SIGTERM: the gateway logs its lines' counters on exit
wait "$gateway_pid" 2>/dev/null || true
line_report=$(grep -E 'line bench .*garbled frame' "$WORK_DIR/gateway.log" | tail -n 1) ||
    fail "the gateway logged no line counters on exit"
shared_garbled=$(sed -nE 's/.* ([0-9]+) garbled frame\(s\).*/\1/p' <<<"$line_report")
line_counts=$(sed -nE 's/.*\): ([0-9]+ sent, [0-9]+ answered, [0-9]+ timeout\(s\), [0-9]+ bad repl(y|ies)),.*/\1/p' <<<"$line_report")
[[ -n $shared_garbled && -n $line_counts ]] || fail "unexpected line counters: $line_report"

kill "$RELAY_PID" 2>/dev/null || true  # SIGTERM: the relay prints its counts
wait "$RELAY_PID" 2>/dev/null || true
relay_report=$(grep -E '^paced_relay: master->device' "$WORK_DIR/relay.log") || fail "the relay printed no counts"
relay_priority=$(sed -nE 's/^paced_relay: ready: .*, ([^,]*priority[^,]*)$/\1/p' "$WORK_DIR/relay.log")
relay_gap=$(sed -nE 's/.*longest silence inside a frame ([0-9.]+ ms \(limit [0-9.]+ ms\)), ([0-9]+) gaps.*/\1, \2 longer/p' <<<"$relay_report")

# Wire time of one request: 8 bytes out, 5 + 2 per register back, a 3.5-character silence
# before each (Modbus over serial line V1.02, 2.5.1.1), and no turnaround of the simulated slave.
character_s=$(calc "%.9f" "10 / $BAUD")
transaction_s=$(calc "%.9f" "(8 + 5 + 2 * $REGISTERS) * $character_s + 2 * 3.5 * $character_s")
echo "line $BAUD baud, 10 bits a character, writes up to $JITTER_MS ms late; FC3 of $REGISTERS registers at unit $UNIT:" \
     "$(calc "%.2f" "1e3 * $transaction_s") ms of wire time a request, capacity $(calc "%.1f" "1 / $transaction_s") req/s"
echo "relay ($relay_priority): longest silence inside a frame $relay_gap than the limit"
echo "a. a plain master (libmodbus) alone: $plain_rate req/s, $plain_failed failed (${DURATION} s each)"
echo "b. loopwire's serial master alone: $alone_rate req/s, $alone_failed failed, $alone_garbled garbled frames"
echo "c. $CLIENTS clients through the gateway: $shared_rate req/s, $shared_failed failed; $shared_details"
echo "   the gateway's line over its run: $line_counts, $shared_garbled garbled frames"
echo "serial line shared: plain master alone $plain_rate req/s, loopwire's master alone $alone_rate req/s," \
     "through the gateway $shared_rate req/s; gateway/plain: $(calc "%.3f" "$shared_rate / $plain_rate")," \
     "gateway/loopwire alone: $(calc "%.3f" "$shared_rate / $alone_rate"); garbled frames: loopwire alone $alone_garbled, gateway $shared_garbled"
