#!/bin/bash
# `loopwire read` / `loopwire write` against a libmodbus Modbus/TCP slave with known contents.
#
# Usage: loopwire_vs_libmodbus_tcp_server.sh LOOPWIRE LIBMODBUS_TCP_SERVER LIBMODBUS_TCP_CLIENT
# Reads compare loopwire's --json output exactly; writes are read back by loopwire and by the
# libmodbus client, so a mistake loopwire makes the same way in both directions cannot hide.

set -euo pipefail
# shellcheck source=tests/support/test_lib.sh
source "$(dirname "$0")/../support/test_lib.sh"

readonly LOOPWIRE=$1 SERVER=$2 CLIENT=$3

# Port 0: the server takes a free port from the kernel and says which.
start_tcp_server server.log "$SERVER" 0 "$PEER_LIFETIME"
readonly LINK=tcp://127.0.0.1:$PORT
MASTER=(--link "$LINK" --unit 1 --timeout 1s --retries 0)

# loopwire_json EXPECTED_EXIT ARGS... : runs loopwire, checks its exit status, prints stdout.
loopwire_json() {
    local expected=$1 status=0
    shift
    timeout 10 "$LOOPWIRE" "$@" >"$WORK_DIR/out" 2>"$WORK_DIR/err" || status=$?
    [[ $status -eq $expected ]] ||
        fail "loopwire $*: exit $status, expected $expected; stdout: $(cat "$WORK_DIR/out"); stderr: $(cat "$WORK_DIR/err")"
    cat "$WORK_DIR/out"
}

# Expected contents (see libmodbus_tcp_server.cpp): holding a = 0x1000 + a, input a = 100 a,
# coil a = (a % 4 == 1), discrete a = (a % 5 == 0).
expect_equal "$(loopwire_json 0 read "${MASTER[@]}" holding 0 5 --json)" \
    '{"unit":1,"table":"holding","address":0,"values":[4096,4097,4098,4099,4100]}' "read holding 0 5"
expect_equal "$(loopwire_json 0 read "${MASTER[@]}" input 195 5 --json)" \
    '{"unit":1,"table":"input","address":195,"values":[19500,19600,19700,19800,19900]}' "read input 195 5"
expect_equal "$(loopwire_json 0 read "${MASTER[@]}" coils 0 10 --json)" \
    '{"unit":1,"table":"coils","address":0,"values":[0,1,0,0,0,1,0,0,0,1]}' "read coils 0 10"
expect_equal "$(loopwire_json 0 read "${MASTER[@]}" discrete 3 8 --json)" \
    '{"unit":1,"table":"discrete","address":3,"values":[0,0,1,0,0,0,0,1]}' "read discrete 3 8"

# 200 registers: two requests (125 + 75); check the whole run arithmetically.
values=$(loopwire_json 0 read "${MASTER[@]}" holding 0 200 --json | sed -E 's/.*"values":\[([0-9,]*)\].*/\1/')
expected=$(seq 4096 4295 | paste -sd ,)
expect_equal "$values" "$expected" "read holding 0 200 (split into two requests)"

# Writes with each function: FC6, FC16 (with a negative value), FC5, FC15.
expect_equal "$(loopwire_json 0 write "${MASTER[@]}" holding 10 54321 --json)" \
    '{"unit":1,"table":"holding","address":10,"values":[54321],"broadcast":false}' "write holding 10 54321"
loopwire_json 0 write "${MASTER[@]}" holding 20 7 -1 0x7FFF >/dev/null
loopwire_json 0 write "${MASTER[@]}" coils 3 on >/dev/null
loopwire_json 0 write "${MASTER[@]}" coils 40 1 1 0 1 0 1 1 0 1 --multiple >/dev/null
expect_equal "$(loopwire_json 0 read "${MASTER[@]}" holding 9 3 --json)" \
    '{"unit":1,"table":"holding","address":9,"values":[4105,54321,4107]}' "loopwire reads back holding 9..11"
expect_equal "$(loopwire_json 0 read "${MASTER[@]}" holding 20 3 --json)" \
    '{"unit":1,"table":"holding","address":20,"values":[7,65535,32767]}' "loopwire reads back holding 20..22"

# The independent reader.
libmodbus_read() {
    timeout 10 "$CLIENT" 127.0.0.1 "$PORT" 1 read "$@" || fail "libmodbus_tcp_client read $* failed"
}
expect_equal "$(libmodbus_read holding 9 3)" "4105 54321 4107" "libmodbus reads holding 9..11"
expect_equal "$(libmodbus_read holding 20 3)" "7 65535 32767" "libmodbus reads holding 20..22"
expect_equal "$(libmodbus_read coils 0 6)" "0 1 0 1 0 1" "libmodbus reads coils 0..5"
expect_equal "$(libmodbus_read coils 40 9)" "1 1 0 1 0 1 1 0 1" "libmodbus reads coils 40..48"

# Past the server's tables: exception 2 -> exit 5, for reads and writes.
loopwire_json 5 read "${MASTER[@]}" holding 199 2 >/dev/null
loopwire_json 5 write "${MASTER[@]}" coils 200 1 >/dev/null
grep -q "exception 2" "$WORK_DIR/err" || fail "the exception is not named: $(cat "$WORK_DIR/err")"
echo "ok: reads and writes past the tables exit 5 with exception 2"

# Nobody listening: a link error (exit 3), not a timeout.
kill "$LAST_PID"
wait "$LAST_PID" 2>/dev/null || true
loopwire_json 3 read "${MASTER[@]}" holding 0 1 >/dev/null
echo "ok: a refused connection exits 3"
echo PASS
