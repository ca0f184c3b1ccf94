#!/usr/bin/env bash
# `loopwire gateway` with an [mqtt] table against a real mosquitto broker on a free loopback
# port: the simulated devices' values appear retained, a `mosquitto_pub` set writes to the
# device and is answered on set/result, an independent client (paho) checks the Home Assistant
# discovery documents against Home Assistant's documented keys, and SIGTERM leaves the gateway
# and its devices "offline", retained.
set -u
loopwire=${1:?usage: mqtt_gateway_test.sh path/to/loopwire}
source "$(dirname "$0")/../support/test_lib.sh"
python=/usr/bin/python3
broker_program=/usr/sbin/mosquitto
if [[ ! -x $broker_program ]]; then echo "SKIP: $broker_program is not installed (Debian package mosquitto)"; exit 0; fi

# A port nothing listens on now (mosquitto cannot be given port 0); a small race, accepted.
port=$($python -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
printf 'listener %s 127.0.0.1\nallow_anonymous true\npersistence false\n' "$port" >"$WORK_DIR/mosquitto.conf"
start_background broker.log timeout 100 "$broker_program" -c "$WORK_DIR/mosquitto.conf"
wait_for_text "$WORK_DIR/broker.log" "running"

cat >"$WORK_DIR/plant.toml" <<TOML
[gateway]
name = "plant1"

[[lines]]
name = "sim"
link = "rtu:virtual?baud=19200"

[[lines.devices]]
name = "oven"
device = "tc10@3"
poll = "200ms"
parameters = ["measured_value", "set_point", "control_state", "alarm_1_state"]

[modbus_tcp]
enabled = false

[mqtt]
broker = "mqtt://127.0.0.1:$port"
writes = true
discovery = "homeassistant"
TOML

start_background gateway.log timeout 100 "$loopwire" gateway --config "$WORK_DIR/plant.toml"
gateway_pid=$LAST_PID
topic=loopwire/plant1/oven

# sub TOPIC : the first (retained) message on TOPIC, 10 s at most.
first_message=(mosquitto_sub -h 127.0.0.1 -p "$port" -C 1 -W 10 -t)
sub() { timeout 15 "${first_message[@]}" "$1" 2>&1; }

check gateway-online 0 "online" "${first_message[@]}" loopwire/plant1/status
check device-online 0 "online" "${first_message[@]}" "$topic/status"
value=$(sub "$topic/measured_value")
if [[ $value =~ ^-?[0-9]+(\.[0-9]+)?$ ]]; then count_pass; else echo "FAIL measured-value-is-a-number: '$value'"; failures=$((failures + 1)); fi
check meta-has-the-unit 0 '"unit"' "${first_message[@]}" "$topic/set_point/meta"

# A set from mosquitto_pub: answered on set/result, and the polls read it back.
timeout 15 mosquitto_sub -h 127.0.0.1 -p "$port" -t "$topic/set_point/set/result" -C 1 -W 10 >"$WORK_DIR/result.out" 2>&1 &
result_pid=$!
sleep 0.5  # the result's subscriber is in place
check set-is-sent 0 "" mosquitto_pub -h 127.0.0.1 -p "$port" -q 1 -t "$topic/set_point/set" -m 210
wait "$result_pid"
if grep -q '"ok":true' "$WORK_DIR/result.out"; then count_pass; else count_failure set-result-ok "$WORK_DIR/result.out"; fi
read_back() { [[ $(sub "$topic/set_point") =~ ^210(\.0+)?$ ]]; }
wait_for 10 "set_point 210 on the broker" read_back
count_pass

# The README's commands, as printed, with the test broker's port.
readme=$(dirname "$0")/../../README.md
mapfile -t readme_commands < <(awk '/^```sh/{f=1;next} /^```/{f=0} f' "$readme" | grep -E '^mosquitto_(sub|pub) ')
((${#readme_commands[@]} == 2)) || fail "expected the README's mosquitto_sub and mosquitto_pub, found: ${readme_commands[*]}"
for command in "${readme_commands[@]}"; do
    eval "words=(${command/-h 127.0.0.1/-h 127.0.0.1 -p $port})"
    status=0
    timeout 3 "${words[@]}" >"$WORK_DIR/readme.out" 2>&1 || status=$?
    case ${words[0]} in
        mosquitto_sub) [[ $status -eq 124 ]] && grep -q "^loopwire/plant1/oven/set_point 210" "$WORK_DIR/readme.out" && count_pass ||
                         count_failure "README: $command (exit $status)" "$WORK_DIR/readme.out" ;;
        *) [[ $status -eq 0 ]] && count_pass || count_failure "README: $command (exit $status)" "$WORK_DIR/readme.out" ;;
    esac
done

# Home Assistant's view, through an independent client.
check discovery-documents 0 "checked, 0 problems" $python "$(dirname "$0")/ha_discovery_check.py" "$port" homeassistant loopwire/plant1 \
  sensor number select binary_sensor

# SIGTERM: a clean stop leaves "offline" retained for the gateway and each device.
kill -TERM "$gateway_pid"
wait "$gateway_pid"
check gateway-offline 0 "offline" "${first_message[@]}" loopwire/plant1/status
check device-offline 0 "offline" "${first_message[@]}" "$topic/status"
finish
