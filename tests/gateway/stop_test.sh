#!/usr/bin/env bash
# A gateway told to stop while its line waits for a reply that will not come (nothing answers on
# the far end of the pseudo-terminal, the line's timeout a minute) stops without waiting the
# timeout out (session/serial_master.cpp, ~SerialMaster): a SIGTERM from systemd or Ctrl-C ends
# it in moments, with exit status 0, whatever the timeout. The bound, 30 s, is half the timeout:
# a gateway that waited would take the whole minute, however loaded the machine.
set -u
loopwire=${1:?usage: stop_test.sh path/to/loopwire}
source "$(dirname "$0")/../support/test_lib.sh"

gateway_end=$WORK_DIR/ttyGateway
silent_end=$WORK_DIR/ttySilent
socat_pair "$gateway_end" "$silent_end"

cat >"$WORK_DIR/plant.toml" <<TOML
[[lines]]
name = "quiet-line"
link = "rtu:$gateway_end?baud=19200&parity=none"
timeout = "60s"

[[lines.devices]]
name = "oven"
device = "tc10@1"
poll = "1s"
parameters = ["measured_value"]

[modbus_tcp]
enabled = false
TOML

# What the gateway sends comes out at the silent end; its first byte says a poll is on the wire
# and the line waits for the reply.
start_background silent_end.bytes timeout 60 head -c 1 "$silent_end"
reader=$LAST_PID
start_background gateway.log timeout 120 "$loopwire" gateway --config "$WORK_DIR/plant.toml"
gateway=$LAST_PID
wait_for 60 "the gateway's first poll at $silent_end" test -s "$WORK_DIR/silent_end.bytes"
wait "$reader" 2>/dev/null

started=$SECONDS
kill -TERM "$gateway"
stopped() { ! kill -0 "$gateway" 2>/dev/null; }
wait_for 30 "the gateway to stop on SIGTERM while its line waited for a reply (timeout 60s); log: $(tail -n 5 "$WORK_DIR/gateway.log")" stopped
wait "$gateway"
status=$?
expect stop-status test "$status" -eq 0
# Its last word, the line's statistics, is said on the way out.
expect stop-said grep -q "line quiet-line .* sent" "$WORK_DIR/gateway.log"
echo "stopped $((SECONDS - started)) s after SIGTERM"
finish
