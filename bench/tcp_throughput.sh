#!/bin/bash
# Loopback Modbus/TCP throughput: `loopwire simulate` against libmodbus's own slave and against
# a bare ping-pong server (one read and one write per request, no Modbus logic: the floor),
# measured in the same run by the same libmodbus client (read 10 holding registers, one request
# at a time).
#
# Usage: bench/tcp_throughput.sh BUILD_DIR [REQUESTS] [ROUNDS]    (20000 requests, 3 rounds)
# Each round measures the three servers one after the other; the figures are each server's
# median over the rounds, so that a moment of a busy machine moves no ratio by itself.
# Builds nothing: BUILD_DIR must hold loopwire, bench/tcp_throughput_client,
# bench/libmodbus_tcp_server and bench/pingpong_server (cmake --build BUILD_DIR).
#
# Server and client are both pinned to CPU 0 (taskset -c 0). On small VMs cross-CPU wake-ups
# dominate a request/response loop (PEERS.md: ~6,000 requests/s spread over two CPUs, ~30,000
# pinned), which would drown the difference between the two servers.
set -euo pipefail

if [[ $# -lt 1 || $# -gt 3 ]]; then
    echo "usage: $0 BUILD_DIR [REQUESTS] [ROUNDS]" >&2
    exit 2
fi
readonly BUILD_DIR=$1 REQUESTS=${2:-20000} ROUNDS=${3:-3}
readonly LOOPWIRE=$BUILD_DIR/loopwire
readonly CLIENT=$BUILD_DIR/bench/tcp_throughput_client
readonly LIBMODBUS_SERVER=$BUILD_DIR/bench/libmodbus_tcp_server
readonly PINGPONG_SERVER=$BUILD_DIR/bench/pingpong_server
for program in "$LOOPWIRE" "$CLIENT" "$LIBMODBUS_SERVER" "$PINGPONG_SERVER"; do
    [[ -x $program ]] || { echo "$0: $program is missing: build it first (cmake --build $BUILD_DIR)" >&2; exit 2; }
done
[[ $REQUESTS =~ ^[1-9][0-9]*$ ]] || { echo "$0: REQUESTS must be a positive number, not '$REQUESTS'" >&2; exit 2; }
[[ $ROUNDS =~ ^[1-9][0-9]*$ ]] || { echo "$0: ROUNDS must be a positive number, not '$ROUNDS'" >&2; exit 2; }

# shellcheck source=tests/support/test_lib.sh
source "$(dirname "$0")/../tests/support/test_lib.sh"

# measure NAME SERVER_COMMAND... : starts the server pinned to CPU 0 on a kernel-chosen port,
# runs the pinned client against it, stops the server, leaves the requests per second in RATE.
# Every server names its port: "listening on port N" (loopwire and ping-pong on stderr,
# libmodbus's on stdout).
measure() {
    local name=$1
    shift
    start_tcp_server "$name.log" taskset -c 0 "$@"
    # The client's limit grows with the request count; even 1,000 requests/s stays inside it.
    timeout $((30 + REQUESTS / 1000)) taskset -c 0 "$CLIENT" 127.0.0.1 "$PORT" "$REQUESTS" 1 \
        >"$WORK_DIR/$name.client" 2>&1 ||
        fail "the client failed against $name: $(cat "$WORK_DIR/$name.client")"
    kill "$LAST_PID" 2>/dev/null || true
    wait "$LAST_PID" 2>/dev/null || true
    RATE=$(sed -nE 's/^requests\/s: ([0-9.]+)$/\1/p' "$WORK_DIR/$name.client")
    [[ -n $RATE ]] || fail "the client printed no rate against $name: $(cat "$WORK_DIR/$name.client")"
}

median() { tr ' ' '\n' <<<"$*" | sort -n | awk '{ v[NR] = $1 } END { print (NR % 2) ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2 }'; }
loopwire_rates=() libmodbus_rates=() pingpong_rates=()
for ((round = 1; round <= ROUNDS; ++round)); do
    measure loopwire "$LOOPWIRE" simulate --link tcp://127.0.0.1:0 --unit 1 --duration 10m
    loopwire_rates+=("$RATE")
    measure libmodbus "$LIBMODBUS_SERVER" 0 600
    libmodbus_rates+=("$RATE")
    measure pingpong "$PINGPONG_SERVER" 0
    pingpong_rates+=("$RATE")
    echo "round $round: loopwire ${loopwire_rates[-1]} req/s, libmodbus ${libmodbus_rates[-1]} req/s, ping-pong ${pingpong_rates[-1]} req/s"
done
loopwire_rate=$(median "${loopwire_rates[@]}")
libmodbus_rate=$(median "${libmodbus_rates[@]}")
pingpong_rate=$(median "${pingpong_rates[@]}")
ratio() { awk -v a="$1" -v b="$2" 'BEGIN { printf "%.2f", a / b }'; }
echo "$REQUESTS requests of 10 holding registers each, server and client pinned to CPU 0; medians of $ROUNDS round(s)"
echo "loopwire: $loopwire_rate req/s, libmodbus: $libmodbus_rate req/s, ping-pong: $pingpong_rate req/s"
echo "loopwire/libmodbus: $(ratio "$loopwire_rate" "$libmodbus_rate"), loopwire/ping-pong: $(ratio "$loopwire_rate" "$pingpong_rate")"
