#!/usr/bin/env bash
# The Sparkplug B session of `loopwire gateway` across restarts, reloads and an outage, against
# a real mosquitto broker, watched by the independent observer (sparkplug_check.py):
#   1. [sparkplug] state_file: three runs of the gateway are born with bdSeq 0, 1 and 2;
#   2. SIGHUP reloads that leave [sparkplug] as it is keep the session (no NDEATH, no NBIRTH):
#      one changing only [http] listen says nothing at all, one removing a device sends exactly
#      its DDEATH, one adding it back exactly its DBIRTH;
#   3. store and forward: the broker itself is stopped (SIGTERM) for 30 s while the devices'
#      values change, and a new one started on the same port; after NBIRTH and the DBIRTHs, every
#      value the node kept arrives once, in its order, with is_historical and its own timestamp,
#      before the live ones; and the furnace's output values are those the gateway's [history]
#      recorded for the outage (sparkplug_outage_values.py), each once;
#   4. the same with the gateway stopped during the outage (10 s of it) and started again once
#      the broker is back: the values it kept in its history file arrive after the births, once.
# The observer outlives the broker's restarts: it keeps an MQTT 5 session the broker persists
# (persistence, QoS 0 messages queued for it), so what the node sends before the observer is
# connected again is delivered to it, in order, after a record of the restart.
#
# SPARKPLUG_KEEP_DIR=DIR keeps the recording and the logs there (the work folder is removed).
set -u
loopwire=${1:?usage: sparkplug_session_test.sh path/to/loopwire}
# shellcheck source=tests/support/test_lib.sh
source "$(dirname "$0")/../support/test_lib.sh"
budget_end=$((SECONDS + 265))
# shellcheck source=tests/gateway/sparkplug_observer_lib.sh
source "$(dirname "$0")/sparkplug_observer_lib.sh"
record_options=(--session 600)
# (user root: a broker started as root keeps the right to save its sessions in the work folder.)
start_recording 295 "persistence true" "persistence_location $WORK_DIR/" "queue_qos0_messages true" \
  "max_queued_messages 0" "user root"
now_ms() { $python -c 'import time; print(int(time.time() * 1000))'; }
count_since() { sp count "$recording" --edge cabinet1 --after-line "$@"; }

# stop_broker NAME : SIGTERM to the broker (it saves the sessions), until it has stopped.
stop_broker() {
  kill -TERM "$broker"
  wait_for 20 "the broker to stop ($1)" stopped "$broker"
}

http_port_a=$(free_port)
http_port_b=$(free_port)
# plant_config HTTP_PORT WITH_KILN : oven (TC10), furnace (AC20, whose main_output_value moves
# nearly every poll) and kiln (TC10, which the reloads remove and add back) on a simulated line.
plant_config() {
cat <<TOML
[gateway]
name = "plant1"

[[lines]]
name = "sim"
link = "rtu:virtual?baud=115200"

[[lines.devices]]
name = "oven"
device = "tc10@3"
poll = "100ms"
parameters = ["measured_value", "set_point", "control_state"]

[[lines.devices]]
name = "furnace"
device = "ac20@1"
poll = "100ms"
parameters = ["carbon_potential", "probe_temperature", "main_set_point", "main_output_value"]
TOML
if [[ $2 == yes ]]; then
cat <<TOML

[[lines.devices]]
name = "kiln"
device = "tc10@4"
poll = "100ms"
parameters = ["measured_value", "set_point"]
TOML
fi
cat <<TOML

[modbus_tcp]
enabled = false

[log]
statistics = "off"

[http]
listen = "127.0.0.1:$1"

[history]
database = "plant.db"

[sparkplug]
broker = "mqtt://127.0.0.1:$MQTT_PORT"
group_id = "plant"
edge_node_id = "cabinet1"
state_file = "sparkplug.state"
store_and_forward = "1m"
TOML
}
plant_config "$http_port_a" yes >"$WORK_DIR/plant.toml"
check config-accepted-store-in-history 0 "store and forward: kept in the history file too" "$loopwire" gateway --config "$WORK_DIR/plant.toml" --check

########## 1. bdSeq 0, 1, 2 over two restarts (state_file)

start_run() {  # LOG
  start_background "$1" timeout 200 "$loopwire" gateway --config "$WORK_DIR/plant.toml"
  gateway=$LAST_PID
}
stop_run() {  # NAME
  local before status=0
  before=$(lines_now)
  kill -TERM "$gateway"
  wait_for 30 "gateway $1 to stop on SIGTERM" stopped "$gateway"
  wait "$gateway" || status=$?
  same "$1-exit-status" "$status" 0
  await "$1-ndeath" 20 --type NDEATH --edge cabinet1 --after-line "$before"
}
bdseqs=()
for run in 1 2 3; do
  before=$(lines_now)
  start_run "gateway$run.log"
  must_await "run$run-nbirth" 60 --type NBIRTH --edge cabinet1 --after-line "$before"
  birth=$found
  bdseqs+=("$(value_at "$birth" bdSeq)")
  ((run < 3)) && stop_run "run$run"
done
same bdseq-over-two-restarts "${bdseqs[*]}" "0 1 2"
same state-file-holds-the-next "$(cat "$WORK_DIR/sparkplug.state")" "bdSeq 3"

########## 2. Reloads that leave [sparkplug] as it is

for device in oven furnace kiln; do
  must_await "dbirth-$device" 60 --type DBIRTH --edge cabinet1 --device "$device" --after-line "$birth"
done
session_start=$(lines_now)

# reload CONFIG_ARGS... : writes the configuration, sends SIGHUP and waits until the next gateway
# runs and the node has carried its session over; then until the furnace's data flows again.
reloads=0
carried_over() { (($(grep -c "carries on across the reload" "$WORK_DIR/gateway3.log") >= $1)); }
reload() {
  plant_config "$@" >"$WORK_DIR/plant.toml"
  reloads=$((reloads + 1))
  kill -HUP "$(pgrep -P "$gateway" | head -n 1)"
  wait_for 30 "reload $reloads to carry the session over" carried_over "$reloads"
  await "reload$reloads-data-flows" 30 --type DDATA --edge cabinet1 --device furnace --after-line "$(lines_now)"
}

before=$(lines_now)
reload "$http_port_b" yes
same http-port-reload-no-session-messages "$(count_since "$before" --type NBIRTH,NDEATH,DBIRTH,DDEATH)" 0
grep -qF "HTTP API and dashboard on http://127.0.0.1:$http_port_b" "$WORK_DIR/gateway3.log" && count_pass ||
  count_failure "the reload moved the HTTP API to port $http_port_b" "$WORK_DIR/gateway3.log"

before=$(lines_now)
reload "$http_port_b" no
await kiln-removed-ddeath 20 --type DDEATH --edge cabinet1 --device kiln --after-line "$before"
same kiln-removed-only-its-ddeath "$(count_since "$before" --type NBIRTH,NDEATH,DBIRTH,DDEATH)" 1

before=$(lines_now)
reload "$http_port_b" yes
await kiln-added-dbirth 30 --type DBIRTH --edge cabinet1 --device kiln --after-line "$before"
same kiln-added-only-its-dbirth "$(count_since "$before" --type NBIRTH,NDEATH,DBIRTH,DDEATH)" 1
same session-bdseq-unchanged "$(sp count "$recording" --type NBIRTH --edge cabinet1 --after-line "$session_start")" 0

########## 3. Store and forward across a 30 s outage of the broker

await furnace-live-before-outage 20 --type DDATA --edge cabinet1 --device furnace --after-line "$(lines_now)"
outage_start=$(lines_now)
cut_ms=$(now_ms)
outage_began=$SECONDS
stop_broker outage
# The outage itself: a fixed 30 s, for the values to change meanwhile (nothing to wait for).
sleep 30
restart_broker broker2.log
echo "    outage: $((SECONDS - outage_began)) s"
must_await nbirth-after-outage 60 --type NBIRTH --edge cabinet1 --after-line "$outage_start"
rebirth=$found
same bdseq-after-outage "$(value_at "$rebirth" bdSeq)" 3
back_ms=$(value_at "$rebirth" bdSeq --what text | sed -nE 's/.* ts=([0-9]+).*/\1/p')
await furnace-data-after-outage 30 --type DDATA --edge cabinet1 --device furnace --after-line "$rebirth"
wait_for 20 "the node to say what it forwarded" grep -qsE "store and forward: [0-9]+ values" "$WORK_DIR/gateway3.log"
told=$(sed -nE 's/.*store and forward: ([0-9]+) values of the outage forwarded.*/\1/p' "$WORK_DIR/gateway3.log" | tail -n 1)
echo "    node: $(grep -oE "store and forward: .*" "$WORK_DIR/gateway3.log" | tail -n 1)"
# Every historical value of the outage: taken after the cut (with a second of slack for a
# sample taken just before it) and before the NBIRTH that ended it; the furnace's output alone
# changes nearly every 100 ms poll, so 30 s give many more than 20.
figures=$(sp historical "$recording" --edge cabinet1 --after-line "$outage_start" --from-ms $((cut_ms - 1000)) \
  --to-ms "$back_ms" --at-least 20) && count_pass || count_failure "store-and-forward figures: $figures"
echo "    observer: $figures"
same historical-received-is-what-the-node-forwarded "$(sed -nE 's/^historical=([0-9]+) .*/\1/p' <<<"$figures")" "$told"
same historical-duplicates "$(sed -nE 's/.* duplicates=([0-9]+) .*/\1/p' <<<"$figures")" 0
same historical-out-of-order "$(sed -nE 's/.* out_of_order=([0-9]+) .*/\1/p' <<<"$figures")" 0

# The same values from another record of them: the furnace's output as the gateway's [history]
# recorded it (every change the polls found, in SQLite) between the last value the observer saw
# before the outage and the DBIRTH after it, each there once as a historical value.
sp series "$recording" --edge cabinet1 --device furnace --metric main_output_value >"$WORK_DIR/series.txt"
compared=$($python "$here/sparkplug_outage_values.py" "$WORK_DIR/plant.db" furnace main_output_value "$outage_start" \
  <"$WORK_DIR/series.txt") && count_pass || count_failure "every-outage-value-once-as-historical: $compared"
echo "    history against observer: $compared"

########## 4. The gateway stopped during the outage, started again once the broker is back

await furnace-live-before-restart 20 --type DDATA --edge cabinet1 --device furnace --after-line "$(lines_now)"
outage_start=$(lines_now)
cut_ms=$(now_ms)
outage_began=$SECONDS
stop_broker restart-case
# 10 s of values the node keeps, in memory and in the history file; then the gateway stops.
sleep 10
kill -TERM "$gateway"
wait_for 30 "gateway 3 to stop on SIGTERM with the broker away" stopped "$gateway"
status=0
wait "$gateway" || status=$?
same run3-exit-status-broker-away "$status" 0
stopped_ms=$(now_ms)
restart_broker broker3.log
echo "    outage: $((SECONDS - outage_began)) s, the gateway stopped after 10 s of it"
start_background gateway4.log timeout 100 "$loopwire" gateway --config "$WORK_DIR/plant.toml"
gateway=$LAST_PID
must_await nbirth-after-restart 60 --type NBIRTH --edge cabinet1 --after-line "$outage_start"
back_ms=$(value_at "$found" bdSeq --what text | sed -nE 's/.* ts=([0-9]+).*/\1/p')
await furnace-dbirth-after-restart 30 --type DBIRTH --edge cabinet1 --device furnace --after-line "$found"
wait_for 30 "the next run to say what it forwarded" grep -qsE "store and forward: [0-9]+ values of the outage" \
  "$WORK_DIR/gateway4.log"
grep -qsE "store and forward: [0-9]+ values the last run kept" "$WORK_DIR/gateway4.log" && count_pass ||
  count_failure "the next run read what the last kept" "$WORK_DIR/gateway4.log"
told=$(sed -nE 's/.*store and forward: ([0-9]+) values of the outage forwarded.*/\1/p' "$WORK_DIR/gateway4.log" | tail -n 1)
echo "    node: $(grep -oE "store and forward: .*" "$WORK_DIR/gateway4.log" | tr '\n' ';')"
figures=$(sp historical "$recording" --edge cabinet1 --after-line "$outage_start" --from-ms $((cut_ms - 1000)) \
  --to-ms "$stopped_ms" --at-least 20) && count_pass || count_failure "restart store-and-forward figures: $figures"
echo "    observer: $figures"
same restart-historical-received-is-what-the-node-forwarded "$(sed -nE 's/^historical=([0-9]+) .*/\1/p' <<<"$figures")" "$told"
same restart-historical-duplicates "$(sed -nE 's/.* duplicates=([0-9]+) .*/\1/p' <<<"$figures")" 0
same restart-historical-out-of-order "$(sed -nE 's/.* out_of_order=([0-9]+) .*/\1/p' <<<"$figures")" 0
# Against the history: the changes from the last live value to the gateway's stop (what the next
# run recorded before its births was never kept: it was sent as the births' own values).
sp series "$recording" --edge cabinet1 --device furnace --metric main_output_value >"$WORK_DIR/series.txt"
compared=$($python "$here/sparkplug_outage_values.py" "$WORK_DIR/plant.db" furnace main_output_value "$outage_start" \
  "$stopped_ms" <"$WORK_DIR/series.txt") && count_pass ||
  count_failure "restart-every-outage-value-once-as-historical: $compared"
echo "    history against observer: $compared"
await furnace-live-after-restart 30 --type DDATA --edge cabinet1 --device furnace --after-line "$(lines_now)"
stop_run run4

########## The whole recording against the rules

status=0
sp check "$recording" >"$WORK_DIR/check.out" 2>&1 || status=$?
echo "--- sparkplug_check.py check ---"
cat "$WORK_DIR/check.out"
if ((status == 0)); then count_pass; else count_failure sparkplug-rules; fi
keep_evidence
finish
