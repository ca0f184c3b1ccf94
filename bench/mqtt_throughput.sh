#!/bin/bash
# The gateway's MQTT front on a real mosquitto broker: value changes/s from the poller
# to a subscriber, poll -> subscriber latency (and a plain publisher's, the broker's floor), and
# memory per 1,000 parameters (mqtt_throughput),
# then the peer in the same run: mosquitto_pub sending as many messages over the same broker
# (one message per line, -l), the ratio gateway/mosquitto_pub.
#
# Usage: bench/mqtt_throughput.sh BUILD_DIR [PARAMETERS] [SECONDS]   (default 500 parameters, 5 s)
# Builds nothing: BUILD_DIR must hold bench/mqtt_throughput.
set -euo pipefail
if [[ $# -lt 1 || $# -gt 3 ]]; then
    echo "usage: $0 BUILD_DIR [PARAMETERS] [SECONDS]" >&2
    exit 2
fi
readonly BUILD_DIR=$1 PARAMETERS=${2:-500} DURATION=${3:-5}
readonly BENCH=$BUILD_DIR/bench/mqtt_throughput
[[ -x $BENCH ]] || { echo "$0: $BENCH is missing: build it first (cmake --build $BUILD_DIR)" >&2; exit 2; }
[[ $PARAMETERS =~ ^[1-9][0-9]*$ && $DURATION =~ ^[1-9][0-9]*$ ]] || { echo "$0: PARAMETERS and SECONDS must be positive whole numbers" >&2; exit 2; }
command -v mosquitto_pub >/dev/null || { echo "$0: mosquitto_pub is missing (Debian package mosquitto-clients)" >&2; exit 2; }

# shellcheck source=tests/support/test_lib.sh
source "$(dirname "$0")/../tests/support/test_lib.sh"

start_mosquitto 300 "max_queued_messages 0"
port=$MQTT_PORT

"$BENCH" "$port" "$PARAMETERS" "$DURATION" mqtt | tee "$WORK_DIR/figures.out"
gateway_rate=$(sed -nE 's/^mqtt rate .*: ([0-9]+) value changes\/s.*/\1/p' "$WORK_DIR/figures.out")
messages=$(sed -nE 's/^mqtt rate .*\(([0-9]+) in .*/\1/p' "$WORK_DIR/figures.out")

# The peer: as many messages from mosquitto_pub, QoS 0, received by a subscriber.
timeout 120 mosquitto_sub -h 127.0.0.1 -p "$port" -t bench/peer -C "$messages" >/dev/null &
subscriber=$!
sleep 0.3
start=$(date +%s.%N)
seq 1 "$messages" | timeout 120 mosquitto_pub -h 127.0.0.1 -p "$port" -t bench/peer -l
wait "$subscriber"
end=$(date +%s.%N)
/usr/bin/python3 - "$messages" "$start" "$end" "$gateway_rate" <<'PY'
import sys
messages, start, end, gateway = int(sys.argv[1]), float(sys.argv[2]), float(sys.argv[3]), float(sys.argv[4])
peer = messages / (end - start)
print(f"mosquitto_pub: {peer:.0f} messages/s ({messages} in {end - start:.2f} s); gateway/mosquitto_pub: {gateway / peer:.2f}")
PY
