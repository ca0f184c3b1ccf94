#!/bin/bash
# The gateway at plant scale: 16 simulated lines x 16 TC10s x 40 parameters (10,240 values),
# polled every second, with the MQTT front (Home Assistant discovery), the Sparkplug B node (both
# on a real mosquitto) and the history file on. After a warm-up it samples the gateway's CPU time
# (/proc/PID/stat, user + system) and resident memory (VmRSS, VmHWM) over SECONDS and reads the
# values polled from /metrics, then prints CPU per 1,000 values/s and memory. The simulated
# devices are served by the same process (virtual lines, transport/virtual_bus.hpp), so the CPU
# figure includes their simulation: it is an upper bound of the gateway's own cost.
# Goals: under 2 % of one core per 1,000 values/s, under 100 MB resident.
#
# Usage: bench/gateway_scale.sh BUILD_DIR [SECONDS] [LINES]   (default 30 s, 16 lines)
set -euo pipefail
if [[ $# -lt 1 || $# -gt 3 ]]; then
    echo "usage: $0 BUILD_DIR [SECONDS] [LINES]" >&2
    exit 2
fi
readonly BUILD_DIR=$1 DURATION=${2:-30} LINES=${3:-16} DEVICES=16 PARAMETERS=40
readonly LOOPWIRE=$BUILD_DIR/loopwire
[[ -x $LOOPWIRE ]] || { echo "$0: $LOOPWIRE is missing: build it first (cmake --build $BUILD_DIR --target loopwire)" >&2; exit 2; }
[[ $DURATION =~ ^[1-9][0-9]*$ ]] || { echo "$0: SECONDS must be a positive whole number" >&2; exit 2; }
[[ $LINES =~ ^[1-9][0-9]*$ ]] || { echo "$0: LINES must be a positive whole number" >&2; exit 2; }
[[ -x /usr/sbin/mosquitto ]] || { echo "$0: /usr/sbin/mosquitto is missing (Debian package mosquitto)" >&2; exit 2; }

# shellcheck source=tests/support/test_lib.sh
source "$(dirname "$0")/../tests/support/test_lib.sh"

start_mosquitto 600 "max_queued_messages 0"

# The TC10's first 40 readable holding words that a simulated TC10 answers in any mode.
mapfile -t names < <("$LOOPWIRE" describe tc10 --json | /usr/bin/python3 -c '
import json, sys
profile = json.load(sys.stdin)
readable = [p["name"] for p in profile["parameters"] if "r" in p["access"] and p["table"] == "holding"]
print("\n".join(readable[:'"$PARAMETERS"']))')
((${#names[@]} == PARAMETERS)) || { echo "$0: the TC10 profile has only ${#names[@]} readable words" >&2; exit 1; }
parameter_list=$(printf '"%s", ' "${names[@]}")
parameter_list="[${parameter_list%, }]"

config=$WORK_DIR/plant.toml
{
    printf '[gateway]\nname = "scale"\n\n'
    for ((line = 0; line < LINES; ++line)); do
        printf '[[lines]]\nname = "line%02d"\nlink = "rtu:virtual?baud=115200&parity=none"\n\n' "$line"
        for ((unit = 1; unit <= DEVICES; ++unit)); do
            printf '[[lines.devices]]\nname = "l%02dd%02d"\ndevice = "tc10@%d"\npoll = "1s"\nparameters = %s\n\n' \
                "$line" "$unit" "$unit" "$parameter_list"
        done
    done
    printf '[modbus_tcp]\nenabled = false\n\n[http]\nlisten = "127.0.0.1:0"\n\n'
    printf '[mqtt]\nbroker = "mqtt://127.0.0.1:%s"\ndiscovery = "homeassistant"\n\n' "$MQTT_PORT"
    printf '[sparkplug]\nbroker = "mqtt://127.0.0.1:%s"\ngroup_id = "bench"\n\n' "$MQTT_PORT"
    printf '[history]\ndatabase = "%s/history.sqlite"\n' "$WORK_DIR"
} >"$config"
"$LOOPWIRE" gateway --config "$config" --check >/dev/null

start_background gateway.log "$LOOPWIRE" gateway --config "$config"
pid=$LAST_PID
http=$(wait_for_log gateway.log 'HTTP API and dashboard on http:..127\.0\.0\.1:([0-9]+)' 60)

# The values polled so far: every device's answered polls times its parameters.
values_polled() {
    curl -sf "http://127.0.0.1:$http/metrics" | awk -v n="$PARAMETERS" '
        /^loopwire_device_polls_total\{/ { polls += $NF }
        /^loopwire_device_poll_errors_total\{/ { failed += $NF }
        END { printf "%d\n", (polls - failed) * n }'
}
cpu_ticks() { awk '{ print $14 + $15 }' "/proc/$pid/stat"; }
memory_kb() { awk -v key="$1:" '$1 == key { print $2 }' "/proc/$pid/status"; }

warmup=$((DURATION < 10 ? DURATION : 10))
echo "gateway_scale: $LINES lines x $DEVICES devices x $PARAMETERS parameters every 1 s, MQTT + Sparkplug + history; warming up $warmup s"
sleep "$warmup"  # the first polls, births and discovery documents are not the steady state measured
values0=$(values_polled)
ticks0=$(cpu_ticks)
start=$(date +%s.%N)
sleep "$DURATION"
values1=$(values_polled)
ticks1=$(cpu_ticks)
end=$(date +%s.%N)
rss=$(memory_kb VmRSS)
hwm=$(memory_kb VmHWM)
threads=$(ls "/proc/$pid/task" | wc -l)
hz=$(getconf CLK_TCK)
/usr/bin/python3 - "$values0" "$values1" "$ticks0" "$ticks1" "$start" "$end" "$hz" "$rss" "$hwm" "$threads" "$((LINES * DEVICES * PARAMETERS))" <<'PY'
import sys
v0, v1, t0, t1 = (int(x) for x in sys.argv[1:5])
start, end, hz = float(sys.argv[5]), float(sys.argv[6]), int(sys.argv[7])
rss, hwm, threads, configured = int(sys.argv[8]), int(sys.argv[9]), int(sys.argv[10]), int(sys.argv[11])
seconds = end - start
rate = (v1 - v0) / seconds
core = (t1 - t0) / hz / seconds  # fraction of one core
print(f"values polled: {rate:.0f}/s of {configured} configured at 1 s ({100 * rate / configured:.0f} %)")
print(f"CPU: {100 * core:.1f} % of one core, {100 * core / (rate / 1000) if rate else float('inf'):.2f} % per 1,000 values/s (goal < 2 %)")
print(f"memory: {rss / 1024:.1f} MB resident, peak {hwm / 1024:.1f} MB (goal < 100 MB); threads: {threads}")
PY
