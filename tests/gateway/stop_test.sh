#!/usr/bin/env bash
# A gateway told to stop while its line waits for a reply that will not come (nothing answers on
# the far end, the line's timeout a minute) stops without waiting the timeout out
# (session::Master::close: session/serial_master.cpp, session/tcp_master.cpp): a SIGTERM from
# systemd or Ctrl-C ends it in moments, with exit status 0, whatever the timeout. Twice: a serial
# line on a pseudo-terminal, and a line to a Modbus TCP device that accepts and never answers.
# The bound, 30 s, is half the timeout: a gateway that waited would take the whole minute,
# however loaded the machine.
set -u
loopwire=${1:?usage: stop_test.sh path/to/loopwire}
source "$(dirname "$0")/../support/test_lib.sh"

# stops_at_once NAME LINK SENT_FILE: a gateway with one line NAME on LINK; once SENT_FILE holds
# the first byte of its first poll (the line waits for the reply), SIGTERM must end it at once.
stops_at_once() {
    local name=$1 link=$2 sent=$3
    cat >"$WORK_DIR/$name.toml" <<TOML
[[lines]]
name = "$name"
link = "$link"
timeout = "60s"

[[lines.devices]]
name = "oven"
device = "tc10@1"
poll = "1s"
parameters = ["measured_value"]

[modbus_tcp]
enabled = false
TOML
    start_background "$name.log" timeout 120 "$loopwire" gateway --config "$WORK_DIR/$name.toml"
    local gateway=$LAST_PID
    wait_for 60 "the gateway's first poll on $name" test -s "$sent"

    local started=$SECONDS
    kill -TERM "$gateway"
    stopped() { ! kill -0 "$gateway" 2>/dev/null; }
    wait_for 30 "the gateway to stop on SIGTERM while $name waited for a reply (timeout 60s); log: $(tail -n 5 "$WORK_DIR/$name.log")" stopped
    wait "$gateway"
    local status=$?
    expect "$name-stop-status" test "$status" -eq 0
    # Its last word, the line's statistics, is said on the way out.
    expect "$name-stop-said" grep -q "line $name .* sent" "$WORK_DIR/$name.log"
    echo "$name: stopped $((SECONDS - started)) s after SIGTERM"
}

# A serial line: what the gateway sends comes out at the silent end of the pair.
gateway_end=$WORK_DIR/ttyGateway
silent_end=$WORK_DIR/ttySilent
socat_pair "$gateway_end" "$silent_end"
start_background silent_end.bytes timeout 60 head -c 1 "$silent_end"
stops_at_once quiet-line "rtu:$gateway_end?baud=19200&parity=none" "$WORK_DIR/silent_end.bytes"

# A Modbus TCP device that accepts the connection, keeps what it is sent, and never answers.
start_tcp_server silent_server.log timeout 60 /usr/bin/python3 -u -c '
import socket, sys
server = socket.socket()
server.bind(("127.0.0.1", 0))
server.listen()
print("listening on port", server.getsockname()[1], flush=True)
connection, _ = server.accept()
with open(sys.argv[1], "ab", buffering=0) as kept:
    while True:
        got = connection.recv(1024)
        if not got:
            break
        kept.write(got)
' "$WORK_DIR/silent_server.bytes"
stops_at_once quiet-device "tcp://127.0.0.1:$PORT" "$WORK_DIR/silent_server.bytes"
finish
