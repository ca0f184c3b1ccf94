#!/usr/bin/env bash
# The loopwire binary as a user meets it: exit codes, error messages, JSON, -v traces, and a
# simulator on a pseudo-terminal and on loopback TCP driven by loopwire's own read/write.
set -u
loopwire=${1:?usage: cli_behaviour_test.sh path/to/loopwire}
source "$(dirname "$0")/../support/test_lib.sh"

# Usage errors: exit 2, naming the bad part.
check no-subcommand 2 "subcommand" "$loopwire"
check bad-baud 2 "12345" "$loopwire" read --link 'rtu:/dev/ttyUSB9?baud=12345' --unit 1 holding 0 1
check bad-scheme 2 "modbus" "$loopwire" read --link 'modbus://x' --unit 1 holding 0 1
check bad-table 2 "unknown table 'holdings'" "$loopwire" read --link "rtu:$WORK_DIR/none" --unit 1 holdings 0 1
check bad-address 2 "address 70000 is out of range" "$loopwire" read --link "rtu:$WORK_DIR/none" --unit 1 holding 70000 1
check bad-timeout 2 "not a duration" "$loopwire" read --link "rtu:$WORK_DIR/none" --timeout soon --unit 1 holding 0 1
# Durations are parsed strictly, where they are typed: no "1.2 s" out of "1.2.3s", no 1 ms out of 0.
check timeout-two-points 2 "--timeout '1.2.3s' is not a duration: write it like 500ms, 2s, 1.5s, 1m or 1h" \
  "$loopwire" read --link "rtu:$WORK_DIR/none" --timeout 1.2.3s --unit 1 holding 0 1
check timeout-zero 2 "--timeout '0' is too short: give at least 1ms" "$loopwire" read --link "rtu:$WORK_DIR/none" --timeout 0 --unit 1 holding 0 1
check timeout-zero-seconds 2 "--timeout '0s' is too short" "$loopwire" dump --link "rtu:$WORK_DIR/none" --device tc10@3 --timeout 0s
check scan-timeout-zero 2 "--timeout '0ms' is too short" "$loopwire" scan --link "rtu:$WORK_DIR/none" --units 1 --timeout 0ms
# A list with an empty element is a unit (or setting) left out by mistake: refused, not skipped.
check scan-units-empty-element 2 "--units '1,,3' has an empty element between commas" \
  "$loopwire" scan --link "rtu:$WORK_DIR/none" --units 1,,3
check scan-bauds-trailing-comma 2 "--bauds '9600,' has an empty element between commas" \
  "$loopwire" scan --link "rtu:$WORK_DIR/none" --units 1 --bauds 9600,
check interval-zero 2 "--interval '0s' is too short: give at least 10ms" \
  "$loopwire" monitor --link "rtu:$WORK_DIR/none" --device tc10@3 --interval 0s
check monitor-count-zero 2 "--count: Value 0 not in range 1" "$loopwire" monitor --link "rtu:$WORK_DIR/none" --device tc10@3 --count 0
check interval-malformed 2 "--interval '1s2' is not a duration" "$loopwire" monitor --link "rtu:$WORK_DIR/none" --device tc10@3 --interval 1s2
check simulate-duration-malformed 2 "--duration '5 s' is not a duration" "$loopwire" simulate --pty "$WORK_DIR/ttyDur" --unit 1 --duration "5 s"
check read-broadcast 2 "unit 0 is broadcast" "$loopwire" read --link "rtu:$WORK_DIR/none" --unit 0 holding 0 1
check bad-coil 2 "coil value 'maybe'" "$loopwire" write --link "rtu:$WORK_DIR/none" --unit 1 coils 0 maybe
check help-lists-exit-codes 0 "4  timeout" "$loopwire" read --help

# The README's first command ends in `loopwire demo`: it must work on a bare machine, and end by
# itself when its output is not a terminal (5 s of JSON lines, one per sample, all three units).
demo_out=$(timeout 20 "$loopwire" demo --port 0 2>"$WORK_DIR/demo.err"); demo_status=$?
check demo-exit 0 "" test "$demo_status" -eq 0
# Every unit answers in some sample (a sample may miss one on a loaded, sanitised machine: the
# monitor then backs off, and says so in that unit's status).
for unit in '"ac20@1":{"status":"ok"' '"rampsoak@2":{"status":"ok"' '"tc10@3":{"status":"ok"'; do
  check "demo-answers-${unit:1:6}" 0 "$unit" printf '%s\n' "$demo_out"
done
check demo-hint 0 "--device tc10@3" cat "$WORK_DIR/demo.err"
# The process moves: the TC10 heats towards its set point of 150 between the first and last sample.
check demo-process-moves 0 "" /usr/bin/python3 -c '
import json, sys
rows = [json.loads(line) for line in sys.argv[1].splitlines() if line.strip()]
pv = [r["devices"]["tc10@3"]["values"]["measured_value"]["value"] for r in rows if r["devices"]["tc10@3"]["status"] == "ok"]
assert len(pv) >= 2 and pv[-1] > pv[0], pv' "$demo_out"

# Link errors: exit 3, naming the port.
check missing-port 3 "$WORK_DIR/none" "$loopwire" read --link "rtu:$WORK_DIR/none" --unit 1 holding 0 1

# decode: 0 for a valid frame, 1 for an invalid one with the reason.
check decode-ac20-fc1 0 '{"protocol":"rtu","unit":100,"function":1,"kind":"request","address":201,"count":14,"values":[],"exception":null,"check_ok":true' \
  "$loopwire" decode --protocol rtu --json 64 01 00 C9 00 0E 64 05
check decode-misprinted-crc 1 "computed CD C1" "$loopwire" decode --protocol rtu 01 90 02 C0 01
# Hex that is not: the refusal says which part is wrong.
check decode-odd-hex-digits 2 "'019' has an odd number of hex digits, and each byte takes two" "$loopwire" decode --protocol rtu 019
check decode-not-a-hex-digit 2 "'g' is not a hex digit" "$loopwire" decode --protocol rtu 01 0g
check decode-0x-bytes 0 "check_ok" "$loopwire" decode --protocol rtu --json 0x01 0x90 0x02 0xCD 0xC1
check decode-ascii-text 0 '"values":[1000]' "$loopwire" decode --protocol ascii --json ':01030203E80F'
check decode-not-hex 2 "not a frame in hex" "$loopwire" decode --protocol rtu 01 0G

# Device profiles: listing, describing, and named access refused before the link is opened.
check devices-lists-three 0 "tc10" "$loopwire" devices
check devices-json 0 '"id":"rampsoak"' "$loopwire" devices --json
check describe-group 0 "SP.HL" "$loopwire" describe tc10 --group SP
check describe-unknown-group 2 "has no group 'nope'" "$loopwire" describe tc10 --group nope
check describe-unknown-device 2 "known profiles: ac20, rampsoak, tc10" "$loopwire" describe tc99
check device-bad-unit 2 "must be 1..255" "$loopwire" read --link "rtu:$WORK_DIR/none" --device tc10@300 SP
check device-unknown-name 2 '"nosuch"' "$loopwire" read --link "rtu:$WORK_DIR/none" --device tc10@3 nosuch
check device-read-only 2 "measured_value (rV) is read-only" "$loopwire" write --link "rtu:$WORK_DIR/none" --device tc10@3 measured_value=3
check device-not-an-assignment 2 "'SP' is not NAME=VALUE" "$loopwire" write --link "rtu:$WORK_DIR/none" --device tc10@3 SP
check device-and-unit-exclusive 2 "excludes" "$loopwire" read --link "rtu:$WORK_DIR/none" --device tc10@3 --unit 3 SP
check device-unknown-numbering 2 "choices: jbus" "$loopwire" read --link "rtu:$WORK_DIR/none" --device ac20@3 --numbering modbus2 SP

# A simulator on a pseudo-terminal, read and written by loopwire.
pty="$WORK_DIR/ttyV0"
start_background sim.log "$loopwire" simulate --pty "$pty" --unit 1 --unit 2 --duration 60s
wait_for_path "$pty"
link="rtu:$pty?baud=19200&parity=even"
check write-registers 0 "wrote 3 register(s)" "$loopwire" write --link "$link" --unit 1 holding 100 1250 -100 0x8000
check read-registers-json 0 '{"unit":1,"table":"holding","address":100,"values":[1250,65436,32768]}' \
  "$loopwire" read --link "$link" --unit 1 holding 100 3 --json
check write-coils 0 "wrote 3 coil(s)" "$loopwire" write --link "$link" --unit 2 coils 7 on 0 1
check read-coils-json 0 '"values":[1,0,1]' "$loopwire" read --link "$link" --unit 2 coils 7 3 --json
check read-many-splits 0 '"address":0' "$loopwire" read --link "$link" --unit 1 holding 0 300 --json
check broadcast-write 0 "broadcast" "$loopwire" write --link "$link" --unit 0 holding 5 77
check broadcast-reached-unit-2 0 '"values":[77]' "$loopwire" read --link "$link" --unit 2 holding 5 1 --json
check unserved-unit-times-out 4 "no reply from unit 9" "$loopwire" read --link "$link" --unit 9 --timeout 200ms --retries 1 holding 0 1
check verbose-trace 0 "TX 01 03 00 64 00 01" "$loopwire" read -v --link "$link" --unit 1 holding 100 1

# The same over loopback TCP.
start_tcp_server tcp.log "$loopwire" simulate --link tcp://127.0.0.1:0 --unit 1 --duration 60s
port=$PORT
check tcp-write 0 "wrote 2" "$loopwire" write --link "tcp://127.0.0.1:$port" --unit 1 holding 10 11 22
check tcp-read 0 '"values":[11,22]' "$loopwire" read --link "tcp://127.0.0.1:$port" --unit 1 holding 10 2 --json
check tcp-unserved-unit 5 "exception 11" "$loopwire" read --link "tcp://127.0.0.1:$port" --unit 3 holding 0 1
check tcp-refused 3 "127.0.0.1" "$loopwire" read --link "tcp://127.0.0.1:1" --unit 1 holding 0 1

# A profile-driven simulated TC10 at unit 3 (device/simulated_device.hpp): scan identifies it
# (word 21 = 20), named reads work, and a set point above SP.HL is refused (TC10 §4.4 B).
tc10_pty="$WORK_DIR/ttyV1"
start_background sim-tc10.log "$loopwire" simulate --pty "$tc10_pty" --device tc10@3 --duration 60s
wait_for_path "$tc10_pty"
check simulate-names-device 0 "unit 3: tc10" cat "$WORK_DIR/sim-tc10.log"
check scan-finds-simulated-tc10 0 '{"unit":3,"device":"tc10"' "$loopwire" scan --link "rtu:$tc10_pty" --units 1-4 --timeout 200ms --json
# A unit named twice is probed and listed once, answering at one line setting.
scanned_twice=$("$loopwire" scan --link "rtu:$tc10_pty" --units 3,3,2-3 --timeout 200ms --json 2>/dev/null)
expect scan-names-a-unit-once test "$(grep -o '"unit":3' <<<"$scanned_twice" | wc -l)" -eq 1
expect scan-lists-the-unit-answering-once grep -q '"lines":\["19200 8E1"\]' <<<"$scanned_twice"
check read-simulated-tc10-sp 0 "SP" "$loopwire" read --link "rtu:$tc10_pty" --device tc10@3 SP
# A device named wrongly is not read as if it were right: the generic unit 1 on TCP and the TC10
# read as an AC20 fail their identification words, a write to them sends nothing, and
# --no-identify talks to the unit anyway.
check wrong-device-read-refused 6 "the device at unit 3 is not ac20@3" \
  "$loopwire" read --link "rtu:$tc10_pty" --device ac20@3 PV
check wrong-device-write-refused 6 "the device at unit 1 is not tc10@1: its instrument_id (word 21) reads 0 where the tc10 profile expects 20" \
  "$loopwire" write --link "tcp://127.0.0.1:$port" --device tc10@1 SP=150
check wrong-device-write-sent-nothing 0 '"values":[0]' "$loopwire" read --link "tcp://127.0.0.1:$port" --unit 1 holding 717 --json
check wrong-device-json-once 6 '"kind":"mismatch"' "$loopwire" read --json --link "tcp://127.0.0.1:$port" --device tc10@1 SP
check no-identify-reads-anyway 0 "set_point" "$loopwire" read --no-identify --link "tcp://127.0.0.1:$port" --device tc10@1 SP
check wrong-device-unknown-says-how-to-find-out 6 "\`loopwire scan --link URL --units 1\` tells what it is" \
  "$loopwire" read --link "tcp://127.0.0.1:$port" --device tc10@1 SP
# A TC10 asked of a simulated AC20: the refusal names both, the one asked for and the one there.
start_tcp_server ac20.log "$loopwire" simulate --link tcp://127.0.0.1:0 --device ac20@1 --duration 60s
check tc10-asked-of-an-ac20-names-both 6 "the device at unit 1 is not tc10@1: its instrument_id (word 21) reads" \
  "$loopwire" read --link "tcp://127.0.0.1:$PORT" --device tc10@1 SP
check tc10-asked-of-an-ac20-says-what-is-there 6 "It answers as ac20@1; --no-identify talks to it as tc10 anyway" \
  "$loopwire" read --link "tcp://127.0.0.1:$PORT" --device tc10@1 SP
check right-device-still-reads 0 "measured_value" "$loopwire" read --link "rtu:$tc10_pty" --device tc10@3 PV
check write-above-sp-hl-refused 5 "exception 3" "$loopwire" write --link "rtu:$tc10_pty" --unit 3 holding 717 30000
# TC10 §4.1, §5.3.7 #62: Pb "1 ... 9999" is in display counts, so at dP = 1 the master refuses
# 1000.0 before sending and names the limit in engineering units; 999.9 is the top. §5.3.1 #2:
# dP 2 is not offered by the J thermocouple the simulator starts with, and the device refuses it.
check write-dp-1 0 "wrote decimal_point = 1" "$loopwire" write --link "rtu:$tc10_pty" --device tc10@3 dp=1
check write-pb-above-counts-refused 2 "proportional_band 1000.0 is above its upper limit 999.9 °C (9999 counts at 1 decimal)" \
  "$loopwire" write --link "rtu:$tc10_pty" --device tc10@3 Pb=1000.0
check write-pb-at-counts-limit 0 "wrote proportional_band = 999.9" "$loopwire" write --link "rtu:$tc10_pty" --device tc10@3 Pb=999.9
# What a write reports is the value as the device now holds it, as a read shows it, not the
# text as typed.
check write-shows-the-value-held 0 "wrote proportional_band = 12.5 °C (raw 125)" \
  "$loopwire" write --link "rtu:$tc10_pty" --device tc10@3 Pb=0012.50
check write-dp-2-thermocouple-refused 5 "exception 3" "$loopwire" write --link "rtu:$tc10_pty" --device tc10@3 dp=2
check simulate-parity-warning 0 "cannot be set to parity none" \
  "$loopwire" simulate --pty "$WORK_DIR/ttyV2" --link "rtu:$WORK_DIR/ttyV2?parity=none" --device rampsoak@1 --duration 300ms

finish
