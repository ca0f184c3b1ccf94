#!/usr/bin/env bash
# The threads of a running `loopwire gateway`, read from /proc as an operator would (the rule:
# the count does not grow with lines, devices or poll intervals, and is at most 5 with history).
# The same for 1 line of 1 device as for 4 virtual lines of 3 devices polled at 3 intervals; two
# more, the history's writer and its reader (queries never wait on a commit, nor commits on a
# query), with [history]. Counted once every device has answered, so every
# line's loop, the engine and the front are up; and again after a SIGHUP that changed a poll
# interval, so a reload starts no thread it keeps. Every configuration serves Modbus TCP, the
# HTTP API, MQTT and Sparkplug B: the fronts are on the engine's loop, no thread of their own.
# Lines to Modbus TCP devices (tcp://) are read on the lines' loop: the same count with them.
# ThreadSanitizer's runtime runs a background thread of its own in every process
# (LOOPWIRE_RUNTIME_THREADS=1 in a TSan build); it is not the gateway's and is not counted.
set -u
loopwire=${1:?usage: gateway_threads_test.sh path/to/loopwire}
runtime_threads=${LOOPWIRE_RUNTIME_THREADS:-0}
[[ $runtime_threads -gt 0 ]] && echo "not counted: $runtime_threads thread(s) of the sanitizer's runtime (named as the process)"
source "$(dirname "$0")/../support/test_lib.sh"

# No broker listens on port 1: the MQTT front and the Sparkplug node keep trying in the background,
# on the engine's loop.
front='[modbus_tcp]
listen = "127.0.0.1:0"
[http]
listen = "127.0.0.1:0"
[mqtt]
broker = "mqtt://127.0.0.1:1"
[sparkplug]
broker = "mqtt://127.0.0.1:1"
group_id = "plant1"
edge_node_id = "threads"'
one_virtual_line() {
  echo '[[lines]]'
  echo 'name = "line0"'
  echo 'link = "rtu:virtual?baud=115200&parity=none"'
  echo '[[lines.devices]]'
  echo 'name = "oven01"'
  echo 'device = "tc10@1"'
  echo 'poll = "1s"'
}
{ one_virtual_line; echo "$front"; } >"$WORK_DIR/one.toml"
four() {  # the first device's poll interval
  for line in 0 1 2 3; do
    echo '[[lines]]'
    echo "name = \"line$line\""
    echo 'link = "rtu:virtual?baud=115200&parity=none"'
    for unit in 1 2 3; do
      echo '[[lines.devices]]'
      echo "name = \"oven$line$unit\""
      echo "device = \"tc10@$unit\""
      case $unit in 1) echo "poll = \"$1\"" ;; 2) echo 'poll = "2s"' ;; 3) echo 'poll = "5s"' ;; esac
      echo "tcp_unit = $((line * 3 + unit))"
    done
  done
  echo "$front"
}
four 1s >"$WORK_DIR/four.toml"
{ four 1s; printf '[history]\ndatabase = "%s"\n' "$WORK_DIR/plant.db"; } >"$WORK_DIR/history.toml"

# threads_of LOG CONFIG DEVICES : starts the gateway, waits until DEVICES devices answered, and
# leaves its thread count in THREADS and their names in NAMES; the gateway in GATEWAY.
threads_of() {
  local log=$1 config=$2 devices=$3
  start_background "$log" "$loopwire" gateway --config "$config"
  GATEWAY=$LAST_PID
  answered() { [[ $(grep -c ') answers' "$WORK_DIR/$log") -ge $devices ]]; }
  wait_for 60 "$devices devices answering in $log" answered
  read_threads
}
read_threads() {
  THREADS=$(($(awk '/^Threads:/ {print $2}' "/proc/$GATEWAY/status") - runtime_threads))
  NAMES=$(cat /proc/"$GATEWAY"/task/*/comm | sort | tr '\n' ' ')
}
stop_gateway() {
  kill -TERM "$GATEWAY"
  wait "$GATEWAY" 2>/dev/null
}

threads_of one.log "$WORK_DIR/one.toml" 1
one=$THREADS
echo "1 line x 1 device: $one threads: $NAMES"
stop_gateway

threads_of four.log "$WORK_DIR/four.toml" 12
four_lines=$THREADS
echo "4 lines x 3 devices at 3 intervals: $four_lines threads: $NAMES"
expect "no thread per line, device or interval" test "$four_lines" -eq "$one"
# A reload that changed a poll interval reopens the lines (the front and its connections stay).
four 3s >"$WORK_DIR/four.toml"
kill -HUP "$GATEWAY"
wait_for 60 "the reload in four.log" grep -q "reloaded" "$WORK_DIR/four.log"
reanswered() { [[ $(grep -c ') answers' "$WORK_DIR/four.log") -ge 24 ]]; }
wait_for 60 "every device answering again after the reload" reanswered
read_threads
echo "after the reload: $THREADS threads: $NAMES"
expect "a reload keeps no thread of the previous configuration" test "$THREADS" -eq "$one"
stop_gateway

# Modbus TCP devices (tcp://, one of them pipelined): their connections are read on the lines'
# loop too, so they add no thread either.
start_tcp_server sim1.log "$loopwire" simulate --link tcp://127.0.0.1:0 --device tc10@1
port1=$PORT
start_tcp_server sim2.log "$loopwire" simulate --link tcp://127.0.0.1:0 --device tc10@1 --device tc10@2
port2=$PORT
{
  for n in 1 2; do
    port=port$n
    echo '[[lines]]'
    echo "name = \"plc$n\""
    echo "link = \"tcp://127.0.0.1:${!port}\""
    [[ $n == 2 ]] && echo 'max_in_flight = 4'
    for unit in $(seq 1 "$n"); do
      echo '[[lines.devices]]'
      echo "name = \"oven$n$unit\""
      echo "device = \"tc10@$unit\""
      echo 'poll = "1s"'
      echo "tcp_unit = $((n * 10 + unit))"
    done
  done
  one_virtual_line
  echo "$front"
} >"$WORK_DIR/tcp.toml"
threads_of tcp.log "$WORK_DIR/tcp.toml" 4
echo "2 Modbus TCP device lines and a virtual one: $THREADS threads: $NAMES"
expect "no thread per Modbus TCP device line" test "$THREADS" -eq "$one"
stop_gateway

threads_of history.log "$WORK_DIR/history.toml" 12
echo "4 lines x 3 devices with history: $THREADS threads: $NAMES"
expect "at most 5 threads with history" test "$THREADS" -le 5
expect "the history's writer and reader are the two more" test "$THREADS" -eq $((one + 2))
expect "the history's writer and reader are named" test "$(grep -o 'lw-history' <<<"$NAMES" | wc -l)" -eq 2
expect "the HTTP API, the MQTT front and the Sparkplug node have no thread of their own" \
  test "$(grep -c 'lw-http\|lw-mqtt\|lw-sparkplug' <<<"$NAMES")" -eq 0
expect "one thread carries the clients, the polls and the writes" test "$(grep -o 'lw-engine' <<<"$NAMES" | wc -l)" -eq 1
expect "the lines and their simulated devices share one" test "$(grep -o 'lw-lines' <<<"$NAMES" | wc -l)" -eq 1
stop_gateway
finish
