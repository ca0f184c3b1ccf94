#!/bin/bash
# The gateway under 20 Modbus/TCP clients at once, two figures:
#
# 1. A simulated 19200-baud RTU line (8N1, the TC10's only byte format) with one TC10 (unit 3):
#    requests/s through the gateway, as a fraction of what the line's wire time allows for that
#    request. The goal is 0.9 or more. The gateway's own line counters (busy %) are shown too.
# 2. A TCP back-end (`loopwire simulate`, one TC10): 20 clients straight to it, then 20 clients
#    through a gateway whose line is one shared connection to it, requests pipelined
#    (max_in_flight = 20); the ratio gateway/direct.
#
# Every client reads 10 holding registers (FC3, addresses 1-10: measured value onwards) and waits
# for each reply before sending again. The gateway polls the TC10 once at start (poll = "60m"),
# which the line counters show apart from the clients' requests.
#
# Usage: bench/gateway_throughput.sh BUILD_DIR [SECONDS]    (SECONDS per measurement, default 10)
# Builds nothing: BUILD_DIR must hold loopwire and bench/gateway_throughput_client.
#
# Pinning: the TCP back-end figures are pinned to CPU 0 (taskset -c 0), as in tcp_throughput.sh:
# on small VMs cross-CPU wake-ups dominate request/response loops on loopback, and the two are
# compared with each other. The serial-line figure is not: it is compared with the wire's own
# time, the gateway spends most of it asleep between timed wake-ups, and piling the 20 clients
# onto the gateway's CPU would only delay those wake-ups, which no real installation does.
set -euo pipefail

if [[ $# -lt 1 || $# -gt 2 ]]; then
    echo "usage: $0 BUILD_DIR [SECONDS]" >&2
    exit 2
fi
readonly BUILD_DIR=$1 DURATION=${2:-10}
readonly LOOPWIRE=$BUILD_DIR/loopwire
readonly CLIENT=$BUILD_DIR/bench/gateway_throughput_client
for program in "$LOOPWIRE" "$CLIENT"; do
    [[ -x $program ]] || { echo "$0: $program is missing: build it first (cmake --build $BUILD_DIR)" >&2; exit 2; }
done
[[ $DURATION =~ ^[1-9][0-9]*$ ]] || { echo "$0: SECONDS must be a positive whole number, not '$DURATION'" >&2; exit 2; }

# shellcheck source=tests/support/test_lib.sh
source "$(dirname "$0")/../tests/support/test_lib.sh"

readonly CLIENTS=20 UNIT=3 ADDRESS=1 REGISTERS=10
readonly BAUD=19200 BITS_PER_CHARACTER=10  # 1 start + 8 data + no parity + 1 stop
# Background processes outlive the measurement only by this much (test_lib.sh: CTest's timeout
# kills with SIGKILL, which runs no trap).
readonly LIFETIME=$((2 * DURATION + 60))

calc() { awk "BEGIN { printf \"$1\", $2 }"; }

# gateway_config FILE LINK [LINE_KEY...] : one line with the TC10 at unit 3 (also its TCP unit),
# polled once an hour (so once, at start), served on a port the kernel chooses; LINE_KEYs are
# more of the line's keys ("max_in_flight = 20").
gateway_config() {
    local file=$1 link=$2
    shift 2
    cat >"$file" <<EOF
[[lines]]
name = "bench"
link = "$link"
timeout = "1s"
$(printf '%s\n' "$@")

[[lines.devices]]
name = "tc10"
device = "tc10@$UNIT"
poll = "60m"
parameters = ["measured_value"]

[modbus_tcp]
listen = "127.0.0.1:0"
EOF
}

# run_clients NAME PORT [PIN...] : the 20 clients for DURATION seconds (under PIN, e.g.
# taskset -c 0); leaves the requests per second in RATE, the number of requests they sent in all
# (warm-up included) in SENT and their latency line in DETAILS.
run_clients() {
    local name=$1 port=$2 out=$WORK_DIR/$1.client
    shift 2
    timeout $((DURATION + 60)) "$@" "$CLIENT" 127.0.0.1 "$port" "$DURATION" "$CLIENTS" "$UNIT" "$ADDRESS" "$REGISTERS" \
        >"$out" 2>&1 || fail "the clients failed against $name: $(cat "$out")"
    RATE=$(sed -nE 's/^requests\/s: ([0-9.]+)$/\1/p' "$out")
    SENT=$(sed -nE 's/^requests sent in all: ([0-9]+)$/\1/p' "$out")
    [[ -n $RATE && -n $SENT ]] || fail "the clients printed no rate against $name: $(cat "$out")"
    DETAILS=$(head -n 1 "$out")
}

# start_gateway NAME CONFIG [PIN...] : starts the gateway (under PIN); leaves its port in PORT,
# its PID in GATEWAY_PID and the time it started in GATEWAY_STARTED.
start_gateway() {
    local name=$1 config=$2
    shift 2
    GATEWAY_STARTED=$EPOCHREALTIME
    start_tcp_server "$name.log" timeout "$LIFETIME" "$@" "$LOOPWIRE" gateway --config "$config"
    GATEWAY_PID=$LAST_PID
}

# stop_gateway NAME : SIGTERM (the gateway drains and logs its lines' counters), then leaves the
# counters line in LINE_REPORT and how long the gateway ran in GATEWAY_LIFE (seconds).
stop_gateway() {
    kill "$GATEWAY_PID" 2>/dev/null || true
    wait "$GATEWAY_PID" 2>/dev/null || true
    GATEWAY_LIFE=$(calc "%.1f" "$EPOCHREALTIME - $GATEWAY_STARTED")
    LINE_REPORT=$(grep -E 'gateway: line bench .*busy [0-9.]+ % of the time' "$WORK_DIR/$1.log" | tail -n 1) ||
        fail "the gateway $1 logged no line counters on exit"
}

# --- 1. The simulated 19200-baud line ---
gateway_config "$WORK_DIR/rtu.toml" "rtu:virtual?baud=$BAUD&parity=none"
start_gateway gateway_rtu "$WORK_DIR/rtu.toml"
# shellcheck disable=SC2153  # PORT is set by start_tcp_server (test_lib.sh)
run_clients gateway_rtu "$PORT"
rtu_rate=$RATE rtu_sent=$SENT rtu_details=$DETAILS
stop_gateway gateway_rtu
rtu_life=$GATEWAY_LIFE
line_sent=$(sed -nE 's/.*: ([0-9]+) sent, .*/\1/p' <<<"$LINE_REPORT")
line_busy=$(sed -nE 's/.*busy ([0-9.]+) % of the time.*/\1/p' <<<"$LINE_REPORT")
[[ -n $line_sent && -n $line_busy ]] || fail "unexpected line counters: $LINE_REPORT"

# Wire time of one request at this speed: RTU request unit + FC + address + count + CRC = 8
# bytes; reply unit + FC + byte count + 2 per register + CRC; a 3.5-character silence before
# each (Modbus over serial line V1.02, 2.5.1.1: the fixed 1.75 ms above 19200 baud, as
# codec::CharacterTiming). The simulated slave has no turnaround delay of its own: it answers
# as soon as the request's silence has passed (session::Slave::reply_after_silence).
request_bytes=8 reply_bytes=$((5 + 2 * REGISTERS))
character_s=$(calc "%.9f" "$BITS_PER_CHARACTER / $BAUD")
gap_s=$(calc "%.9f" "($BAUD > 19200) ? 0.00175 : 3.5 * $character_s")
transaction_s=$(calc "%.9f" "($request_bytes + $reply_bytes) * $character_s + 2 * $gap_s")
capacity=$(calc "%.1f" "1 / $transaction_s")
rtu_fraction=$(calc "%.3f" "$rtu_rate * $transaction_s")

# --- 2. A TCP back-end: direct, then through the gateway ---
start_tcp_server simulate.log taskset -c 0 "$LOOPWIRE" simulate --link tcp://127.0.0.1:0 --device "tc10@$UNIT" \
    --duration "${LIFETIME}s"
simulator_port=$PORT
run_clients direct "$simulator_port" taskset -c 0
direct_rate=$RATE direct_details=$DETAILS
# Pipelined: every client's request goes to the device as it comes, paired with its reply by
# transaction id, as direct clients' requests do.
gateway_config "$WORK_DIR/tcp.toml" "tcp://127.0.0.1:$simulator_port" "max_in_flight = $CLIENTS"
start_gateway gateway_tcp "$WORK_DIR/tcp.toml" taskset -c 0
run_clients gateway_tcp "$PORT" taskset -c 0
tcp_rate=$RATE tcp_details=$DETAILS
stop_gateway gateway_tcp

echo "$CLIENTS clients, each reading $REGISTERS holding registers of unit $UNIT (FC3) one request at a time, ${DURATION} s per figure"
echo "line $BAUD baud 8N1 ($BITS_PER_CHARACTER bits/character): ($request_bytes + $reply_bytes bytes) x $(calc "%.1f" "1e6 * $character_s") us" \
     "+ 2 x $(calc "%.1f" "1e6 * $gap_s") us gap + 0 turnaround = $(calc "%.3f" "1e3 * $transaction_s") ms per request: capacity $capacity req/s"
echo "  clients: $rtu_details"
echo "  gateway's line over its ${rtu_life} s run: $line_sent sent ($rtu_sent by the clients), busy $line_busy % of the time"
echo "gateway to the $BAUD-baud line (not pinned): $rtu_rate req/s = $rtu_fraction of the line's capacity"
echo "  direct: $direct_details"
echo "  through the gateway: $tcp_details"
echo "TCP back-end (all pinned to CPU 0): direct $direct_rate req/s, through the gateway $tcp_rate req/s, gateway/direct: $(calc "%.3f" "$tcp_rate / $direct_rate")"
