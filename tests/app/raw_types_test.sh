#!/usr/bin/env bash
# Generic Modbus devices through the CLI: read and monitor of raw registers with --type (strings
# too), --word-order, --byte-swap, --scale and --base, against a simulated register bank holding
# known IEEE 754 and two's complement words, and the errors of each option.
set -u
loopwire=${1:?usage: raw_types_test.sh path/to/loopwire}
source "$(dirname "$0")/../support/test_lib.sh"

start_tcp_server sim.log timeout 200 "$loopwire" simulate --link tcp://127.0.0.1:0 --unit 5 --duration 180s
link=(--link "tcp://127.0.0.1:$PORT" --timeout 300ms)

# 100: 12.5f big (4148 0000)        102: -3.25f little (0000 C050)   104: 123456789 big (075B CD15)
# 106: -2 little (FFFE FFFF)        108: pi float64 big              112: pi float64 little
# 116: 12.5f big, bytes swapped     118: 4000000000 uint32 big       120: 1234 (04D2), 0xFFFF
"$loopwire" write "${link[@]}" --unit 5 holding 100 0x4148 0 0 0xC050 0x075B 0xCD15 0xFFFE 0xFFFF \
  0x4009 0x21FB 0x5444 0x2D18 0x2D18 0x5444 0x21FB 0x4009 0x4841 0 0xEE6B 0x2800 1234 0xFFFF >"$WORK_DIR/w.out" 2>&1 \
  || fail "writing the known words: $(cat "$WORK_DIR/w.out")"

read5=("$loopwire" read "${link[@]}" --unit 5)
check float32-big 0 '"values":[12.5]' "${read5[@]}" holding 100 --type float32 --json
check float32-little 0 '"values":[-3.25]' "${read5[@]}" holding 102 --type float32 --word-order little --json
check int32-big 0 '"values":[123456789]' "${read5[@]}" holding 104 --type int32 --json
check int32-little 0 '"values":[-2]' "${read5[@]}" holding 106 --type int32 --word-order little --json
check uint32-little 0 '"values":[4294967294]' "${read5[@]}" holding 106 --type uint32 --word-order little --json
check uint32-big 0 '"values":[4000000000]' "${read5[@]}" holding 118 --type uint32 --json
check float64-big 0 '"values":[3.141592653589793]' "${read5[@]}" holding 108 --type float64 --json
check float64-little 0 '"values":[3.141592653589793]' "${read5[@]}" holding 112 --type float64 --word-order little --json
check float32-byte-swap 0 '"values":[12.5]' "${read5[@]}" holding 116 --type float32 --byte-swap --json
check int16 0 '"values":[1234,-1]' "${read5[@]}" holding 120 2 --type int16 --json
check uint16 0 '"values":[1234,65535]' "${read5[@]}" holding 120 2 --type uint16 --json
check json-describes 0 '{"unit":5,"table":"holding","address":100,"type":"float32","word_order":"big","byte_swap":false,"scale":null,"values":[12.5],"registers":[16712,0]}' \
  "${read5[@]}" holding 100 --type float32 --json
# COUNT counts values: 2 float32 values are registers 100-103.
check count-is-values 0 '"registers":[16712,0,0,49232]' "${read5[@]}" holding 100 2 --type float32 --json
check text-output 0 '  100                      12.5  (4148 0000)' "${read5[@]}" holding 100 --type float32
check text-output-second 0 '  102                     -3.25  (0000 C050)' "${read5[@]}" holding 100 2 --type float32 --word-order little
check scale 0 '"values":[123.4]' "${read5[@]}" holding 120 --type int16 --scale 0.1 --json
check scale-json 0 '"scale":0.1' "${read5[@]}" holding 120 --type int16 --scale 0.1 --json
check scale-float 0 '"values":[1.25]' "${read5[@]}" holding 100 --type float32 --scale 0.1 --json
check scale-alone-types-uint16 0 '"values":[6553.5]' "${read5[@]}" holding 121 --scale 0.1 --json
check base-1 0 '"address":101,"type":"float32"' "${read5[@]}" holding 101 --type float32 --base 1 --json
check base-1-value 0 '"values":[12.5]' "${read5[@]}" holding 101 --type float32 --base 1 --json
check base-1-text 0 '  101                      12.5' "${read5[@]}" holding 101 --type float32 --base 1
check base-1-plain-words 0 '"address":121,"base":1,"values":[1234]' "${read5[@]}" holding 121 --base 1 --json
check plain-words-unchanged 0 '{"unit":5,"table":"holding","address":120,"values":[1234,65535]}' "${read5[@]}" holding 120 2 --json

# Errors: exit 2, saying what is wrong and what the choices are.
check unknown-type 2 "unknown type 'float': choose int16, uint16, int32, uint32, float32, float64 or string" "${read5[@]}" holding 100 --type float
check unknown-word-order 2 "unknown word order 'middle': choose big" "${read5[@]}" holding 100 --type float32 --word-order middle
check type-on-coils 2 'apply to registers (holding, input); coils are single bits' "${read5[@]}" coils 0 4 --type int16
check base-1-address-0 2 'address 0 does not exist with --base 1' "${read5[@]}" holding 0 --base 1
check base-2 2 '--base' "${read5[@]}" holding 0 --base 2
check past-last-register 2 '1 float64 value from holding 65534 would need 4 registers, but only 2 remain up to the last address 65535' \
  "${read5[@]}" holding 65534 --type float64
check past-last-register-base-1 2 'up to the last address 65536' "${read5[@]}" holding 65536 --type float32 --base 1
check count-past-end 2 '3 float32 values from holding 65531 would need 6 registers, but only 5 remain' "${read5[@]}" holding 65531 3 --type float32
check scale-zero 2 '--scale 0 would turn every value into 0' "${read5[@]}" holding 100 --scale 0
check scale-malformed 2 "--scale '1e3' is not a factor" "${read5[@]}" holding 100 --scale 1e3
check type-with-device 2 'a --device profile already says how its parameters are encoded' \
  "$loopwire" read "${link[@]}" --device tc10@5 SP --type float32
# The simulator answers a unit it does not serve with exception 0Bh (gateway target failed to respond).
check unit-not-served 5 'exception 11' "$loopwire" read "${link[@]}" --unit 9 holding 100 --type float32

# monitor of raw registers: one line per sample, typed as read types them.
timeout 20 "$loopwire" monitor "${link[@]}" --unit 5 holding 102 2 --type int32 --word-order little --interval 100ms --count 3 \
  --format jsonl --utc >"$WORK_DIR/m.jsonl" 2>"$WORK_DIR/m.err" || count_failure monitor-jsonl-exit "$WORK_DIR/m.err"
if /usr/bin/python3 - "$WORK_DIR/m.jsonl" >"$WORK_DIR/why" 2>&1 <<'PY'
import json, sys
rows = [json.loads(line) for line in open(sys.argv[1]) if line.strip()]
assert len(rows) == 3, rows
for i, row in enumerate(rows, 1):
    assert row["sample"] == i and row["time"].endswith("Z"), row
    assert (row["unit"], row["table"], row["type"], row["word_order"], row["status"]) == (5, "holding", "int32", "little", "ok"), row
    # 102: 0000 C050 is C0500000 little-endian; 104: 075B CD15 is CD15075B.
    assert row["values"] == {"102": -1068498944, "104": -854259877}, row["values"]
PY
then count_pass; else count_failure monitor-jsonl-values "$WORK_DIR/why" "$WORK_DIR/m.jsonl"; fi

check monitor-csv 0 'time,sample,status,errors,holding 101,holding 103' \
  "$loopwire" monitor "${link[@]}" --unit 5 holding 101 2 --type float32 --base 1 --count 1 --format csv
check monitor-csv-row 0 ',1,ok,0,12.5,' \
  "$loopwire" monitor "${link[@]}" --unit 5 holding 101 2 --type float32 --base 1 --count 1 --format csv
check monitor-plain-words 0 '"values":{"120":1234,"121":65535}' \
  "$loopwire" monitor "${link[@]}" --unit 5 holding 120 2 --count 1 --format jsonl
check monitor-table 0 '12.5  4148 0000' \
  "$loopwire" monitor "${link[@]}" --unit 5 holding 100 --type float32 --count 1 --format table --interval 100ms
# A unit that fails shows why in every sample, and the polling goes on.
timeout 20 "$loopwire" monitor "${link[@]}" --unit 9 holding 100 --type float32 --interval 100ms --count 3 \
  --format jsonl >"$WORK_DIR/dead.jsonl" 2>"$WORK_DIR/dead.err" || count_failure monitor-dead-exit "$WORK_DIR/dead.err"
if /usr/bin/python3 - "$WORK_DIR/dead.jsonl" >"$WORK_DIR/why" 2>&1 <<'PY'
import json, sys
rows = [json.loads(line) for line in open(sys.argv[1]) if line.strip()]
assert len(rows) == 3, rows
assert [r["status"] for r in rows] == ["exception"] * 3 and [r["errors"] for r in rows] == [1, 2, 3], rows
assert all(r["values"] == {"100": None} and "exception 11" in r["error"] for r in rows), rows
PY
then count_pass; else count_failure monitor-dead-unit "$WORK_DIR/why" "$WORK_DIR/dead.jsonl"; fi
# Ctrl-C ends a raw monitor cleanly (exit 0).
timeout --preserve-status -s INT 6 "$loopwire" monitor "${link[@]}" --unit 5 holding 100 --type float32 --interval 100ms --format jsonl \
  >"$WORK_DIR/int.jsonl" 2>&1
status=$?
if [[ $status -eq 0 && -s $WORK_DIR/int.jsonl ]]; then count_pass; else count_failure "monitor-ctrl-c (exit $status)" "$WORK_DIR/int.jsonl"; fi

# A raw log appended to, as the named monitor's: one header, the rows of both runs.
for run in 1 2; do
    timeout 20 "$loopwire" monitor "${link[@]}" --unit 5 holding 100 --type float32 --count 2 --interval 100ms \
      --output "$WORK_DIR/raw.csv" --append --rotate-size 10MB >"$WORK_DIR/append.out" 2>&1 || count_failure "monitor-raw-append-run-$run" "$WORK_DIR/append.out"
done
if [[ $(grep -c '^time,sample,status,errors,holding 100$' "$WORK_DIR/raw.csv") -eq 1 && $(grep -c ',ok,0,12.5$' "$WORK_DIR/raw.csv") -eq 4 ]]
then count_pass; else count_failure monitor-raw-append-keeps-one-header "$WORK_DIR/raw.csv"; fi
check monitor-raw-append-other-columns 2 'its CSV header differs' \
  "$loopwire" monitor "${link[@]}" --unit 5 holding 102 --type float32 --count 1 --output "$WORK_DIR/raw.csv" --append

check monitor-neither 2 'monitor takes --device DEVICE@UNIT [NAMES...] (by name), or --unit N TABLE ADDRESS [COUNT]' \
  "$loopwire" monitor "${link[@]}" --count 1
check monitor-no-unit 2 'raw registers need --unit N' "$loopwire" monitor "${link[@]}" holding 100 --count 1
check monitor-unit-and-device 2 'excludes' "$loopwire" monitor "${link[@]}" --unit 5 --device tc10@5 --count 1
check monitor-type-with-device 2 'a --device profile already says' \
  "$loopwire" monitor "${link[@]}" --device tc10@5 --type float32 --count 1
check monitor-odd-type 2 "unknown type 'real'" "$loopwire" monitor "${link[@]}" --unit 5 holding 100 --type real --count 1
check help-count-is-values 0 'holding 100 2 --type float32 reads registers 100-103' "$loopwire" read --help
check monitor-help-count-is-values 0 'holding 100 2 --type float32 reads registers 100-103' "$loopwire" monitor --help
# Strings: ASCII two characters a register, high byte first (or low with --byte-swap, BADC,
# DCBA), an odd length padded with NUL, read up to the first NUL; COUNT counts registers.
write5=("$loopwire" write "${link[@]}" --unit 5)
check string-write 0 '"values":["AB12c"],"registers":[16706,12594,25344]' "${write5[@]}" holding 300 --type string "AB12c" --json
check string-read 0 '"type":"string","word_order":"big","byte_swap":false,"scale":null,"values":["AB12c"],"registers":[16706,12594,25344]' \
  "${read5[@]}" holding 300 3 --type string --json
check string-read-text 0 '    300                     AB12c  (4142 3132 6300)' "${read5[@]}" holding 300 3 --type string
"${write5[@]}" holding 312 0x4344 >/dev/null 2>&1 || fail "writing CD after the string"
check string-padded 0 '"registers":[16706,12544]' "${write5[@]}" holding 310 --type string "AB1" --json
check string-stops-at-nul 0 '"values":["AB1"]' "${read5[@]}" holding 310 3 --type string --json
check string-count-is-registers 0 '"values":["AB12"],"registers":[16706,12594]' "${read5[@]}" holding 300 2 --type string --json
check string-low-byte-first 0 '"registers":[26952,33]' "${write5[@]}" holding 320 --type string --byte-swap "Hi!" --json
check string-badc 0 '"values":["Hi!"]' "${read5[@]}" holding 320 2 --type string --word-order BADC --json
check string-dcba 0 '"values":["Hi!"]' "${read5[@]}" holding 320 2 --type string --word-order DCBA --json
check string-other-byte-order 0 '"values":["iH"]' "${read5[@]}" holding 320 2 --type string --json
check string-monitor 0 ',ok,0,AB12c' "$loopwire" monitor "${link[@]}" --unit 5 holding 300 3 --type string --count 1 --format csv
"${write5[@]}" holding 330 --type string 'say "a,b"' >/dev/null 2>&1 || fail "writing a string with a comma"
check string-monitor-csv-quoted 0 ',ok,0,"say ""a,b"""' "$loopwire" monitor "${link[@]}" --unit 5 holding 330 5 --type string --count 1 --format csv
check string-not-ascii 2 "'Grüße' is not printable ASCII text" "${write5[@]}" holding 300 --type string "Grüße"
check string-too-long 2 'its 250 characters take 125 registers, and one write carries at most 123 (246 characters)' \
  "${write5[@]}" holding 300 --type string "$(printf 'x%.0s' {1..250})"
check string-past-the-end 2 'only 1 remain up to the last address 65535' "${write5[@]}" holding 65535 --type string "ABC"
check string-count-past-the-end 2 'a string of 2 registers from holding 65535' "${read5[@]}" holding 65535 2 --type string
check string-one-text 2 '--type string writes one text, 2 were given' "${write5[@]}" holding 300 --type string AB CD
check string-no-scale 2 '--scale multiplies numbers; a string is text' "${read5[@]}" holding 300 2 --type string --scale 0.1
check string-help 0 'or string (ASCII, two characters a register' "$loopwire" read --help
check string-write-help 0 'string (ASCII, two characters a register' "$loopwire" write --help
finish
