#!/usr/bin/env bash
# Everyday use of the CLI against simulated devices: monitor logs that run unattended (format by
# extension, --append, rotation, local time or UTC, units and special states in CSV), scan
# streaming, Ctrl-C and the line that ignores its settings, the live table sized to the
# terminal with -v traces above it, and the conventions (options before the command, help
# COMMAND, JSON errors, exception names, restore's sides and counts).
set -u
loopwire=$(realpath "${1:?usage: everyday_use_test.sh path/to/loopwire}")
python=/usr/bin/python3
source "$(dirname "$0")/../support/test_lib.sh"

start_tcp_server sim.log "$loopwire" simulate --link tcp://127.0.0.1:0 --device tc10@3 --device rampsoak@5 --duration 100s
tcp="tcp://127.0.0.1:$PORT"
start_tcp_server broken.log "$loopwire" simulate --link tcp://127.0.0.1:0 --device tc10@3 --fault tc10@3:open-input --duration 100s
broken="tcp://127.0.0.1:$PORT"
start_background pty.log "$loopwire" simulate --pty "$WORK_DIR/ttyS" --device tc10@3 --duration 100s
wait_for_path "$WORK_DIR/ttyS"
cd "$WORK_DIR" || fail "no work dir"

pycheck() {  # name, python body (argv[1:] are the remaining arguments)
  local name=$1 body=$2
  shift 2
  if $python - "$@" <<PY >why 2>&1
import csv, glob, json, os, re, sys
$body
PY
  then count_pass; else count_failure "$name" why; fi
}

# ---- monitor --output: the format from the extension ------------------------------------
timeout 20 "$loopwire" monitor --link "$tcp" --device tc10@3 --interval 100ms --count 2 --output log.csv 2>err.txt \
  || count_failure "monitor to log.csv" err.txt
timeout 20 "$loopwire" monitor --link "$tcp" --device tc10@3 --interval 100ms --count 2 --output log.ndjson --utc 2>err.txt \
  || count_failure "monitor to log.ndjson" err.txt
pycheck monitor-format-from-extension '
rows = list(csv.reader(open("log.csv")))
assert rows[0][:4] == ["time", "sample", "tc10@3 status", "tc10@3 errors"] and len(rows) == 3, rows
assert "tc10@3:output_power [%]" in rows[0], rows[0]          # units in the header
assert re.fullmatch(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d\.\d{3}[+-]\d\d:\d\d", rows[1][0]), rows[1]  # local time, offset
lines = [json.loads(l) for l in open("log.ndjson")]
assert len(lines) == 2 and all(l["time"].endswith("Z") for l in lines), lines         # --utc
'
check monitor-format-contradicts-extension 2 "--format jsonl contradicts --output x.csv" \
  "$loopwire" monitor --link "$tcp" --device tc10@3 --count 1 --format jsonl --output x.csv
check monitor-unknown-extension 2 "cannot tell the format from its name" \
  "$loopwire" monitor --link "$tcp" --device tc10@3 --count 1 --output x.txt
check monitor-append-needs-output 2 "add --output FILE" "$loopwire" monitor --link "$tcp" --device tc10@3 --count 1 --append
check monitor-bad-rotate 2 "the one period is daily" "$loopwire" monitor --link "$tcp" --device tc10@3 --count 1 --output r.csv --rotate weekly
check monitor-bad-size 2 "is not a size" "$loopwire" monitor --link "$tcp" --device tc10@3 --count 1 --output r.csv --rotate-size 10XB
check monitor-help-lists-log-options 0 "--rotate-size" "$loopwire" monitor --help

# ---- --append: the header once, a different one refused ---------------------------------
timeout 20 "$loopwire" monitor --link "$tcp" --device tc10@3 --interval 100ms --count 2 --output log.csv --append 2>err.txt \
  || count_failure "monitor --append" err.txt
pycheck monitor-append-keeps-one-header '
rows = list(csv.reader(open("log.csv")))
assert len(rows) == 5 and sum(r[0] == "time" for r in rows) == 1, rows
'
cp log.csv before.csv
check monitor-append-other-columns 2 "its CSV header differs from this monitor's columns" \
  "$loopwire" monitor --link "$tcp" --device tc10@3 PV --count 1 --output log.csv --append
expect monitor-append-refusal-leaves-file cmp -s log.csv before.csv

# ---- rotation by size: nothing lost at the switches -------------------------------------
timeout 30 "$loopwire" monitor --link "$tcp" --device tc10@3 --device rampsoak@5 --interval 50ms --count 40 \
  --output rot.csv --rotate-size 2kB 2>err.txt || count_failure "monitor --rotate-size" err.txt
pycheck monitor-rotates-by-size '
files = sorted(glob.glob("rot.*.csv")) + ["rot.csv"]
assert len(files) >= 2, files
samples = []
for f in files:
    assert os.path.getsize(f) <= 2000, (f, os.path.getsize(f))
    rows = list(csv.reader(open(f)))
    assert rows[0][0] == "time", (f, rows[0])
    samples += [int(r[1]) for r in rows[1:]]
assert samples == list(range(1, 41)), samples
'

# ---- special states by name -------------------------------------------------------------
timeout 20 "$loopwire" monitor --link "$broken" --device tc10@3 --count 1 --output broken.csv 2>err.txt \
  || count_failure "monitor of an open input" err.txt
pycheck monitor-csv-special-state-by-name '
rows = list(csv.DictReader(open("broken.csv")))
assert rows[0]["tc10@3:measured_value [°C]"] == "out-of-range", rows[0]  # the unit its temperature_unit word says
'

# ---- the live table: fitted to a small terminal, -v traces above it -----------------------
pycheck monitor-table-fits-terminal-and-traces-stay-above '
import fcntl, pty, select, signal, struct, termios, time
pid, fd = pty.fork()
if pid == 0:
    os.execv(sys.argv[1], [sys.argv[1], "-v", "monitor", "--link", sys.argv[2], "--device", "tc10@3", "--device", "rampsoak@5",
                           "all", "--interval", "300ms"])
fcntl.ioctl(fd, termios.TIOCSWINSZ, struct.pack("HHHH", 12, 60, 0, 0))
out = b""
deadline = time.time() + 15
while time.time() < deadline and out.count(b"sample ") < 4:
    if select.select([fd], [], [], 0.1)[0]:
        try: out += os.read(fd, 65536)
        except OSError: break
os.kill(pid, signal.SIGINT)
end = time.time() + 5
while time.time() < end:
    if select.select([fd], [], [], 0.1)[0]:
        try:
            chunk = os.read(fd, 65536)
        except OSError: break
        if not chunk: break
        out += chunk
os.waitpid(pid, 0)
text = out.decode("utf-8", "replace")
assert " TX " in text and "more lines" in text, text[-600:]
# Every line drawn fits 59 columns, escape sequences aside; no frame is taller than 11 lines.
plain = re.sub(r"\x1b\[[0-9;?]*[A-Za-z]", "", text)
table_lines = [l for l in plain.replace("\r\n", "\n").split("\n") if " TX " not in l and " RX " not in l]
assert max(len(l.replace("\r", "")) for l in table_lines) <= 59, max(table_lines, key=len)
assert all(int(n) <= 11 for n in re.findall(r"\x1b\[(\d+)F", text)), set(re.findall(r"\x1b\[(\d+)F", text))
# A trace erases the table, is printed, and the table follows it again.
assert re.search(r"\x1b\[\d+F\x1b\[J\r\d\d:\d\d:\d\d\.\d{6} (TX|RX) [^\n]*\n\rloopwire monitor", text), text[:800]
' "$loopwire" "$tcp"

# ---- scan: each unit as found, Ctrl-C keeps them, a line that ignores its settings --------
# 300 ms for a reply: the simulator on the other end of the pseudo-terminal shares a loaded
# CI machine (ASan, two test jobs on two cores), and a reply missed would drop a setting from the
# list below. The silent units cost 16 x 300 ms.
timeout 60 "$loopwire" scan --link "rtu:$WORK_DIR/ttyS" --units 1-5 --bauds 9600,19200 --parities none,even \
  --timeout 300ms >scan.out 2>scan.err || count_failure "scan sweep" scan.err
check scan-warns-line-ignores-settings 0 "the line probably ignores line settings" cat scan.err
# One simulated unit at four settings is one unit, listed once with every setting that found it.
check scan-counts-each-unit-once 0 "1 unit(s) answered" cat scan.out
check scan-lists-the-settings-of-a-unit 0 "answered at 9600 8N1, 9600 8E1, 19200 8N1, 19200 8E1" cat scan.out
if (($(grep "^unit   3  tc10 " scan.out | grep -vc " also at ") == 1 && $(grep -c " also at " scan.out) == 3)); then count_pass
else count_failure scan-prints-the-unit-once-then-where-else scan.out; fi
"$loopwire" scan --link "rtu:$WORK_DIR/ttyS" --units 1-247 --timeout 300ms >scan2.out 2>scan2.err &
scan_pid=$!
unit_printed() { grep -q "^unit   3  tc10" scan2.out; }
wait_for 15 "scan to print unit 3 while still scanning" unit_printed
kill -0 "$scan_pid" 2>/dev/null || count_failure "scan ended before Ctrl-C (not streaming?)" scan2.out
kill -INT "$scan_pid"
status=0; wait "$scan_pid" || status=$?
if [ "$status" -eq 130 ] && grep -q "1 unit(s) answered before the scan was interrupted" scan2.out; then count_pass
else echo "    exit $status"; count_failure scan-ctrl-c-keeps-what-it-found scan2.out; fi

# ---- options before the command, help COMMAND ---------------------------------------------
"$loopwire" -v read --link "$tcp" --device tc10@3 SP >before.out 2>before.err || count_failure "-v before read" before.err
"$loopwire" read --link "$tcp" --device tc10@3 SP -v >after.out 2>after.err || count_failure "-v after read" after.err
if grep -q " TX " before.err && [ "$(grep -c ' TX ' before.err)" -eq "$(grep -c ' TX ' after.err)" ] && cmp -s before.out after.out
then count_pass; else count_failure options-before-the-command before.err after.err; fi
check timeout-before-command 0 "set_point" "$loopwire" --timeout 2s --json read --link "$tcp" --device tc10@3 SP
"$loopwire" help monitor >help1.out; "$loopwire" monitor --help >help2.out
expect help-command-is-command-help cmp -s help1.out help2.out
"$loopwire" help >help3.out; "$loopwire" --help >help4.out
expect help-alone-is-program-help cmp -s help3.out help4.out
check help-unknown-command 2 "there is no command 'nope'" "$loopwire" help nope
# The hidden commands (shell completion, man pages) are for tools, not offered to people.
if "$loopwire" help nope 2>&1 | grep -q "__complete"; then count_failure help-lists-hidden-commands; else count_pass; fi
# A typo gets the nearest command, not CLI11's "A subcommand is required".
check typo-nearest-command 2 "there is no command 'reed'; did you mean 'read'?" "$loopwire" reed
check typo-far-from-any 2 "there is no command 'frobnicate': choose one of read, write" "$loopwire" frobnicate

# ---- read --json: a JSON error object on failure -------------------------------------------
pyjson() {  # name, want-status, python assertion on `doc`, command...
  local name=$1 want=$2 body=$3
  shift 3
  local status=0
  "$@" >json.out 2>json.err || status=$?
  if [ "$status" -eq "$want" ] && $python -c "
import json, sys
doc = json.load(open('json.out'))
$body" >why 2>&1; then count_pass; else echo "    exit $status"; count_failure "$name" json.out why; fi
}
pyjson read-json-link-error 3 'assert doc["kind"] == "link" and "none" in doc["error"], doc' \
  "$loopwire" read --json --link "rtu:$WORK_DIR/none" --unit 1 holding 0 1
pyjson read-json-timeout 4 'assert doc["kind"] == "timeout" and doc["error"], doc' \
  "$loopwire" read --json --link "rtu:$WORK_DIR/ttyS?parity=none" --unit 9 --timeout 200ms holding 0 1
# The simulator on TCP answers for a unit it does not serve as a gateway would: exception 0Bh.
# One failure, one report: the JSON object on stdout and nothing again on stderr.
if [[ ! -s json.err ]]; then count_pass; else count_failure read-json-timeout-says-it-once json.err; fi
pyjson read-json-device-timeout 4 'assert doc["kind"] == "timeout" and "no reply from unit 9" in doc["error"], doc' \
  "$loopwire" read --json --link "rtu:$WORK_DIR/ttyS?parity=none" --device tc10@9 --timeout 200ms PV
if [[ ! -s json.err && $(wc -l <json.out) -eq 1 ]]; then count_pass; else count_failure device-read-json-timeout-says-it-once json.out json.err; fi
pyjson read-json-exception-0B 5 'assert doc["code"] == 11 and doc["exception"] == "gateway target device failed to respond", doc' \
  "$loopwire" read --json --link "$tcp" --unit 9 --timeout 200ms holding 0 1
pyjson read-json-exception 5 'assert doc["kind"] == "exception" and doc["code"] == 2 and doc["exception"] == "illegal data address", doc' \
  "$loopwire" read --json --link "$tcp" --unit 3 holding 9000 1
pyjson read-json-usage 2 'assert doc["kind"] == "usage" and "unit 0 is broadcast" in doc["error"], doc' \
  "$loopwire" read --json --link "$tcp" --unit 0 holding 0 1
# Arguments the command line itself refuses are a JSON document on stdout too, and said once.
pyjson read-json-bad-unit 2 'assert doc["kind"] == "usage" and "--unit" in doc["error"], doc' \
  "$loopwire" read --json --link "$tcp" --unit 256 holding 0 1
if [[ ! -s json.err ]]; then count_pass; else count_failure read-json-bad-unit-says-it-once json.err; fi
pyjson read-json-unknown-option 2 'assert doc["kind"] == "usage" and "--bogus" in doc["error"], doc' \
  "$loopwire" read --json --link "$tcp" --unit 9 holding 0 --bogus
pyjson read-json-no-link 2 'assert doc["kind"] == "usage" and "--link" in doc["error"], doc' \
  "$loopwire" read --unit 9 holding 0 --json
check bad-unit-without-json 2 "loopwire: error: --unit" "$loopwire" read --link "$tcp" --unit 256 holding 0 1

# ---- exception names of every standard code ------------------------------------------------
for code in "0A:gateway path unavailable" "0B:gateway target device failed to respond" "08:memory parity error" "06:server device busy"; do
  check "decode-exception-${code%%:*}" 0 "(${code#*:})" "$loopwire" decode --protocol tcp --direction reply 00 01 00 00 00 03 01 83 "${code%%:*}"
done

# ---- restore: which side is which, and "1 difference" ---------------------------------------
timeout 30 "$loopwire" dump --link "$tcp" --device tc10@3 --output tc10.json >dump.out 2>&1 || count_failure "dump" dump.out
timeout 10 "$loopwire" write --link "$tcp" --device tc10@3 alarm_1_threshold=123 >write.out 2>&1 || count_failure "write" write.out
timeout 30 "$loopwire" restore --link "$tcp" --device tc10@3 tc10.json --dry-run >restore.out 2>&1 || count_failure "restore --dry-run" restore.out
if grep -q "^1 difference between the device tc10@3 and the file tc10.json (device now -> file" restore.out \
   && grep -qE "^  alarm_1_threshold +123(\.0)? .*-> " restore.out; then count_pass
else count_failure restore-says-sides-and-one-difference restore.out; fi

finish
