#!/usr/bin/env bash
# Home Assistant discovery as Home Assistant takes it, against a real mosquitto: a gateway with
# three simulated controllers (TC10, AC20, ramp/soak) publishes documents that an independent
# checker (ha_discovery_check.py: voluptuous schemas of the MQTT platforms, every template
# rendered with Jinja2 against every status word and a value) accepts, with ranges only from the
# devices' limits; reloaded with two of them, the third leaves nothing retained behind (no
# discovery document, no value, status or availability), and the two that stay never flap.
set -u
loopwire=${1:?usage: ha_discovery_test.sh path/to/loopwire}
source "$(dirname "$0")/../support/test_lib.sh"
python=/usr/bin/python3
skip() { echo "SKIP: $1 (scripts/setup installs it)"; exit 77; }
[[ -x /usr/sbin/mosquitto ]] || skip "/usr/sbin/mosquitto is not installed (Debian package mosquitto)"
command -v mosquitto_sub >/dev/null || skip "mosquitto_sub is not installed (Debian package mosquitto-clients)"
for module in paho.mqtt voluptuous jinja2; do
  $python -c "import $module" 2>/dev/null || skip "$module is not importable by $python"
done

start_mosquitto 200
port=$MQTT_PORT
# The dashboard's port is in the documents (configuration_url): one the kernel had free.
http_port=$(free_port)

# plant_config WITH_KILN : the gateway's configuration, with or without the ramp/soak controller.
plant_config() {
cat <<TOML
[gateway]
name = "plant1"

[[lines]]
name = "sim"
link = "rtu:virtual?baud=19200"

[[lines.devices]]
name = "oven"
device = "tc10@3"
poll = "300ms"
parameters = ["measured_value", "set_point", "set_point_low_limit", "set_point_high_limit", "control_state",
              "output_power", "alarm_status", "alarm_1_state"]

[[lines.devices]]
name = "furnace"
device = "ac20@1"
poll = "300ms"
parameters = ["carbon_potential", "main_set_point", "main_output_value", "main_output_low_limit",
              "main_output_high_limit", "local_remote", "secondary_output_value"]
TOML
if [[ $1 == with-kiln ]]; then
cat <<TOML

[[lines.devices]]
name = "kiln"
device = "rampsoak@5"
poll = "300ms"
parameters = ["process_value", "set_value", "output_percentage", "output_limit", "pattern_1_segment_1_output_limit"]
TOML
fi
cat <<TOML

[modbus_tcp]
enabled = false

[http]
listen = "127.0.0.1:$http_port"

[mqtt]
broker = "mqtt://127.0.0.1:$port"
writes = true
discovery = "homeassistant"
TOML
}
plant_config with-kiln >"$WORK_DIR/plant.toml"

# Everything published from now on, with retain flags: what a reload must not flap.
start_background everything.log timeout 150 mosquitto_sub -h 127.0.0.1 -p "$port" -v -F '%r %t %p' -t 'homeassistant/#' \
  -t 'loopwire/plant1/#'
everything_pid=$LAST_PID
wait_for 30 "the recorder's subscription" bash -c "mosquitto_pub -h 127.0.0.1 -p $port -t loopwire/plant1/probe/x -m probe -r &&
  grep -q 'loopwire/plant1/probe/x probe' '$WORK_DIR/everything.log'"
# The probe stays retained: a topic under the gateway's prefix that no configuration publishes.

start_background gateway.log timeout 140 "$loopwire" gateway --config "$WORK_DIR/plant.toml"
gateway_pid=$LAST_PID
for device in oven furnace kiln; do
  wait_for 40 "$device online" bash -c "timeout 5 mosquitto_sub -h 127.0.0.1 -p $port -C 1 -W 4 -t loopwire/plant1/$device/availability 2>/dev/null | grep -q online"
done
# Every device's limit words read, so that the ranges below are the devices'.
limits_read() {
  timeout 5 mosquitto_sub -h 127.0.0.1 -p "$port" -C 1 -W 4 -t loopwire/plant1/furnace/main_output_value/meta 2>/dev/null |
    grep -q '"max":[0-9]'
}
wait_for 40 "the AC20's output limits in its meta" limits_read

checker=("$python" "$(dirname "$0")/ha_discovery_check.py" "$port" homeassistant loopwire/plant1
         sensor number select binary_sensor climate)
# The AC20's output: its range is ñ.OLL .. ñ.OLH as the device holds them (0.0 .. 100.0 %), not
# the word's -3276.8 .. 3276.7; the ramp/soak set value has no limit: no min/max at all; a
# segment's output limit is the 0 .. 100 % its profile states; local/remote is a select; the
# thermostat's slider has a range (the checker compares it with SP.LL .. SP.HL as read).
expectations=(--expect=plant1_furnace_main_output_value=min:0.0 --expect=plant1_furnace_main_output_value=max:100.0
              --expect=plant1_kiln_set_value=min:absent --expect=plant1_kiln_set_value=max:absent
              --expect=plant1_kiln_pattern_1_segment_1_output_limit=max:100.0
              --expect='plant1_furnace_local_remote=options:["local","remote"]'
              --expect=plant1_oven_control_loop=action_topic:'"loopwire/plant1/oven/output_power"'
              --expect=plant1_oven_control_loop=min_temp:present --expect=plant1_oven_control_loop=max_temp:present
              --expect=plant1_status=state_topic:'"loopwire/plant1/status"')
if timeout 60 "${checker[@]}" "${expectations[@]}" >"$WORK_DIR/check1.out" 2>&1; then count_pass; else count_failure three-devices "$WORK_DIR/check1.out"; fi
tail -n 1 "$WORK_DIR/check1.out"
expect configuration-url grep -q "\"configuration_url\":\"http://127.0.0.1:$http_port/\"" "$WORK_DIR/everything.log"
wait_for_text "$WORK_DIR/gateway.log" "cleared 1 retained topic the configuration no longer publishes" 20
count_pass

# retained_topics PATTERN... : the topics a fresh subscriber gets retained (within 3 s).
retained_topics() {
  local args=() pattern
  for pattern in "$@"; do args+=(-t "$pattern"); done
  timeout 5 mosquitto_sub -h 127.0.0.1 -p "$port" --retained-only -W 3 -v "${args[@]}" 2>/dev/null | cut -d' ' -f1 | sort
}
retained_topics 'homeassistant/#' 'loopwire/plant1/#' >"$WORK_DIR/retained-before.txt"
kiln_before=$(grep -c kiln "$WORK_DIR/retained-before.txt")
echo "retained before the reload: $(wc -l <"$WORK_DIR/retained-before.txt") topics, $kiln_before of the kiln"
expect kiln-retained-before test "$kiln_before" -ge 10
reload_line=$(wc -l <"$WORK_DIR/everything.log")

loopwire_pid=$(pgrep -P "$gateway_pid" | head -n 1)
plant_config without-kiln >"$WORK_DIR/plant.toml"
kill -HUP "$loopwire_pid"
swept_twice() { (($(grep -c "retained topics\? the configuration no longer publishes" "$WORK_DIR/gateway.log") >= 2)); }
wait_for 40 "the reloaded gateway's sweep" swept_twice
retained_topics 'homeassistant/#' 'loopwire/plant1/#' >"$WORK_DIR/retained-after.txt"
echo "retained after the reload: $(wc -l <"$WORK_DIR/retained-after.txt") topics"
if grep -q kiln "$WORK_DIR/retained-after.txt"; then count_failure kiln-leaves-nothing-retained "$WORK_DIR/retained-after.txt"; else count_pass; fi
# Everything of the two devices that stay is still retained.
grep -v kiln "$WORK_DIR/retained-before.txt" >"$WORK_DIR/staying-before.txt"
missing=$(comm -23 "$WORK_DIR/staying-before.txt" "$WORK_DIR/retained-after.txt")
if [[ -z $missing ]]; then count_pass; else echo "$missing" >"$WORK_DIR/missing.txt"; count_failure staying-topics-kept "$WORK_DIR/missing.txt"; fi
# No flap: since the reload, only the kiln's topics were emptied (an empty retained payload).
tail -n +"$((reload_line + 1))" "$WORK_DIR/everything.log" | awk 'NF == 2' >"$WORK_DIR/emptied.txt"
echo "emptied since the reload: $(wc -l <"$WORK_DIR/emptied.txt") topics, $(grep -vc kiln "$WORK_DIR/emptied.txt") of the others"
if grep -v kiln "$WORK_DIR/emptied.txt" | grep -q .; then count_failure no-flap "$WORK_DIR/emptied.txt"; else count_pass; fi
kiln_documents=$(grep -c '^homeassistant/.*kiln' <(cut -d' ' -f2 "$WORK_DIR/emptied.txt"))
expect kiln-documents-emptied test "$kiln_documents" -ge 5
if timeout 60 "${checker[@]}" >"$WORK_DIR/check2.out" 2>&1; then count_pass; else count_failure two-devices "$WORK_DIR/check2.out"; fi
tail -n 1 "$WORK_DIR/check2.out"
kill "$everything_pid"
kill -TERM "$gateway_pid"
wait "$gateway_pid"
finish
