#!/bin/bash
# The Sparkplug B edge node against the plain MQTT front, in the same run on the same mosquitto
# broker: 20 devices x 50 metrics (1,000 parameters), every one changing in every
# sample. For each front: value changes/s from the poller's cache to a subscriber (Sparkplug:
# metrics in the DDATA it decodes), poll -> subscriber latency, memory; then the ratios
# sparkplug/mqtt.
#
# Usage: bench/sparkplug_throughput.sh BUILD_DIR [SECONDS]   (default 5 s per measurement)
# Builds nothing: BUILD_DIR must hold bench/mqtt_throughput.
set -euo pipefail
if [[ $# -lt 1 || $# -gt 2 ]]; then
    echo "usage: $0 BUILD_DIR [SECONDS]" >&2
    exit 2
fi
readonly BUILD_DIR=$1 DURATION=${2:-5} PARAMETERS=1000
readonly BENCH=$BUILD_DIR/bench/mqtt_throughput
[[ -x $BENCH ]] || { echo "$0: $BENCH is missing: build it first (cmake --build $BUILD_DIR)" >&2; exit 2; }
[[ $DURATION =~ ^[1-9][0-9]*$ ]] || { echo "$0: SECONDS must be a positive whole number" >&2; exit 2; }

# shellcheck source=tests/support/test_lib.sh
source "$(dirname "$0")/../tests/support/test_lib.sh"

start_mosquitto 300 "max_queued_messages 0"
port=$MQTT_PORT

for front in mqtt sparkplug; do
    "$BENCH" "$port" "$PARAMETERS" "$DURATION" "$front" | tee -a "$WORK_DIR/figures.out"
done
/usr/bin/python3 - "$WORK_DIR/figures.out" <<'PY'
import re, sys
text = open(sys.argv[1]).read()
def figure(front, pattern):
    found = re.search(rf"^{front} {pattern}", text, re.M)
    if not found:
        sys.exit(f"no {front} figure matching {pattern!r} in:\n{text}")
    return float(found.group(1))
rate = {f: figure(f, r"rate .*: ([0-9]+) value changes/s") for f in ("mqtt", "sparkplug")}
p50 = {f: figure(f, r"latency .*p50 ([0-9.]+) ms") for f in ("mqtt", "sparkplug")}
print(f"sparkplug/mqtt: rate {rate['sparkplug'] / rate['mqtt']:.2f}, latency p50 {p50['sparkplug'] / p50['mqtt']:.2f} "
      f"({rate['sparkplug']:.0f} vs {rate['mqtt']:.0f} value changes/s, p50 {p50['sparkplug']:.2f} vs {p50['mqtt']:.2f} ms)")
PY
