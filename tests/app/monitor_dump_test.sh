#!/usr/bin/env bash
# `loopwire monitor` and `loopwire dump` against simulated devices on one RTU pseudo-terminal:
# rows and names, values that change between samples, one request per planned block, a unit
# that does not answer, the live table on a terminal and Ctrl-C, and dumps checked against
# `loopwire describe --json`.
set -u
loopwire=${1:?usage: monitor_dump_test.sh path/to/loopwire}
python=/usr/bin/python3
source "$(dirname "$0")/../support/test_lib.sh"

pty="$WORK_DIR/ttyM0"
start_background sim.log "$loopwire" simulate --pty "$pty" --device tc10@3 --device rampsoak@5 --duration 100s
wait_for_path "$pty"
link="rtu:$pty"
# The same devices over loopback TCP, where several masters may connect at once (a serial port
# is opened exclusively): a write can then land between two monitor samples.
start_tcp_server tcp.log "$loopwire" simulate --link tcp://127.0.0.1:0 --device tc10@3 --device rampsoak@5 --duration 100s
tcp="tcp://127.0.0.1:$PORT"

# Python checks on JSON lines: exit 0 when the assertion holds, else print why.
jcheck() {  # name, file, python body using `rows` (list of parsed lines)
  local name=$1 file=$2 body=$3
  if $python - "$file" <<PY >"$WORK_DIR/why" 2>&1
import json, re, sys
rows = [json.loads(line) for line in open(sys.argv[1]) if line.strip()]
$body
PY
  then count_pass; else count_failure "$name" "$WORK_DIR/why" "$file"; fi
}

# N rows, every default name of both devices present and read.
timeout 20 "$loopwire" monitor --link "$link" --device tc10@3 --device rampsoak@5 --interval 200ms --count 3 \
  >"$WORK_DIR/rows.jsonl" 2>"$WORK_DIR/mon.err" || count_failure "monitor-jsonl exit status" "$WORK_DIR/mon.err"
jcheck monitor-jsonl-rows "$WORK_DIR/rows.jsonl" '
assert len(rows) == 3, len(rows)
names = {"tc10@3": ["measured_value", "set_point", "operating_set_point", "output_power", "alarm_status", "control_state"],
         "rampsoak@5": ["process_value", "set_value", "output_percentage", "controller_status"]}
for i, row in enumerate(rows, 1):
    # Local time with its offset by default (--utc gives ...Z).
    assert row["sample"] == i and re.fullmatch(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d\.\d{3}[+-]\d\d:\d\d", row["time"]), row
    for device, wanted in names.items():
        d = row["devices"][device]
        assert d["status"] == "ok" and d["errors"] == 0, d
        assert list(d["values"]) == wanted, list(d["values"])
        for name in wanted:
            assert d["values"][name]["text"] is not None and d["values"][name]["age"] < 0.2, (name, d["values"][name])
'

# Named selection: DEVICE@UNIT:NAME for one device (a plain name must match on every device).
timeout 20 "$loopwire" monitor --link "$link" --device tc10@3 --device rampsoak@5 --count 1 --format csv \
  tc10@3:output_power rampsoak@5:SV >"$WORK_DIR/rows.csv" 2>"$WORK_DIR/mon.err" || count_failure "monitor-csv exit status" "$WORK_DIR/mon.err"
if [ "$(head -1 "$WORK_DIR/rows.csv")" = "time,sample,tc10@3 status,tc10@3 errors,tc10@3:output_power [%],rampsoak@5 status,rampsoak@5 errors,rampsoak@5:set_value [°C]" ] \
   && [ "$(wc -l <"$WORK_DIR/rows.csv")" -eq 2 ]; then count_pass; else count_failure monitor-csv-columns "$WORK_DIR/rows.csv"; fi

# A unit the device's configuration sets (the TC10's temperature_unit word) is in the CSV header
# once it is read; appending to a file whose header has no unit there (or another one) goes on
# and says, once, which columns now carry which unit.
timeout 20 "$loopwire" monitor --link "$tcp" --device tc10@3 PV SP --count 1 --format csv >"$WORK_DIR/units.csv" 2>"$WORK_DIR/units.err"
check csv-header-has-the-devices-unit 0 "tc10@3:measured_value [°C],tc10@3:set_point [°C]" head -1 "$WORK_DIR/units.csv"
printf 'time,sample,tc10@3 status,tc10@3 errors,tc10@3:measured_value,tc10@3:set_point [°F]\n' >"$WORK_DIR/old.csv"
check csv-append-explains-units 0 'column "tc10@3:measured_value" is now "tc10@3:measured_value [°C]"' \
  timeout 20 "$loopwire" monitor --link "$tcp" --device tc10@3 PV SP --count 2 --interval 100ms --output "$WORK_DIR/old.csv" --append
check csv-append-explains-another-unit 0 'column "tc10@3:set_point [°F]" is now "tc10@3:set_point [°C]"' \
  timeout 20 "$loopwire" monitor --link "$tcp" --device tc10@3 PV SP --count 1 --output "$WORK_DIR/old.csv" --append
if [ "$(wc -l <"$WORK_DIR/old.csv")" -eq 4 ]; then count_pass; else count_failure csv-append-adds-the-rows "$WORK_DIR/old.csv"; fi
check csv-append-still-refuses-other-columns 2 "its CSV header differs" \
  timeout 20 "$loopwire" monitor --link "$tcp" --device tc10@3 PV OUT --count 1 --output "$WORK_DIR/old.csv" --append

# A value written between samples shows up changed in the following ones. 30 samples give the
# write 8 s to land even on a slow machine.
timeout 30 "$loopwire" monitor --link "$tcp" --device rampsoak@5 set_value --interval 300ms --count 30 \
  --output "$WORK_DIR/change.jsonl" 2>"$WORK_DIR/change.err" &
monitor_pid=$!
two_samples_written() { [ -e "$WORK_DIR/change.jsonl" ] && [ "$(wc -l <"$WORK_DIR/change.jsonl")" -ge 2 ]; }
wait_for 10 "two monitor samples in change.jsonl before the write" two_samples_written
timeout 10 "$loopwire" write --link "$tcp" --device rampsoak@5 SV=425 >"$WORK_DIR/write.out" 2>&1 || count_failure "write SV" "$WORK_DIR/write.out"
wait "$monitor_pid" || count_failure "monitor-change exit status" "$WORK_DIR/change.err"
jcheck monitor-sees-written-value "$WORK_DIR/change.jsonl" '
texts = [r["devices"]["rampsoak@5"]["values"]["set_value"]["text"] for r in rows]
assert len(rows) == 30, len(rows)
assert texts[0] != "425.0" and texts[-1] == "425.0", texts
first = texts.index("425.0")
assert rows[first]["devices"]["rampsoak@5"]["values"]["set_value"]["changed"] is True, rows[first]
'

# Values moving as the process runs: a TC10 at --speed 100 heading for SP 300 from a 25 °C room.
start_tcp_server fast.log "$loopwire" simulate --link tcp://127.0.0.1:0 --device tc10@3 --speed 100 --duration 60s
fast="tcp://127.0.0.1:$PORT"
timeout 10 "$loopwire" write --link "$fast" --device tc10@3 set_point=300 >"$WORK_DIR/fast-write.out" 2>&1 || count_failure "write SP" "$WORK_DIR/fast-write.out"
timeout 20 "$loopwire" monitor --link "$fast" --device tc10@3 --interval 300ms --count 5 \
  >"$WORK_DIR/moving.jsonl" 2>"$WORK_DIR/moving.err" || count_failure "monitor-moving exit status" "$WORK_DIR/moving.err"
jcheck monitor-values-move-with-the-process "$WORK_DIR/moving.jsonl" '
values = [r["devices"]["tc10@3"]["values"] for r in rows]
pv = [v["measured_value"]["value"] for v in values]
assert len(rows) == 5 and None not in pv, pv
assert all(a <= b for a, b in zip(pv, pv[1:])) and pv[-1] > pv[0], ("PV should rise towards 300", pv)
assert any(v["measured_value"]["changed"] for v in values[1:]), values
assert values[0]["output_power"]["value"] > 0, values[0]["output_power"]  # heating, 275 °C below SP
assert all(v["operating_set_point"]["value"] == 300 for v in values), values
'

# One request per planned block: a monitor sample sends exactly what `read --device` of the same
# names sends, nothing more (both skip their identification words, which a monitor otherwise
# reads with its first poll and the first after a failure). A request sent again at once is not counted: a block whose reply has the bytes of another
# block's (two registers holding 0) is asked twice the first time, as that reply could be a copy.
count_tx() { grep ' TX ' "$1" | awk '{ $1 = ""; if ($0 != previous) n++; previous = $0 } END { print n + 0 }'; }
timeout 20 "$loopwire" read -v --no-identify --link "$link" --device tc10@3 measured_value set_point operating_set_point output_power \
  alarm_status control_state >/dev/null 2>"$WORK_DIR/r1.err"
timeout 20 "$loopwire" read -v --no-identify --link "$link" --device rampsoak@5 process_value set_value output_percentage controller_status >/dev/null 2>"$WORK_DIR/r2.err"
timeout 20 "$loopwire" monitor -v --no-identify --link "$link" --device tc10@3 --device rampsoak@5 --interval 100ms --count 3 \
  >/dev/null 2>"$WORK_DIR/mv.err"
per_sample=$(( $(count_tx "$WORK_DIR/r1.err") + $(count_tx "$WORK_DIR/r2.err") ))
if [ "$per_sample" -ge 2 ] && [ "$(count_tx "$WORK_DIR/mv.err")" -eq $((3 * per_sample)) ]; then count_pass
else echo "    requests per sample $per_sample, monitor sent $(count_tx "$WORK_DIR/mv.err") in 3 samples"; count_failure monitor-one-request-per-block "$WORK_DIR/mv.err"; fi

# Unit 7 is not served: it shows as not answering, is retried with back-off (not every sample),
# and the served units keep the 300 ms cadence.
timeout 30 "$loopwire" monitor -v --link "$link" --device tc10@3 --device tc10@7 --device rampsoak@5 --interval 300ms \
  --timeout 100ms --count 12 >"$WORK_DIR/dead.jsonl" 2>"$WORK_DIR/dead.err" || count_failure "monitor-dead exit status" "$WORK_DIR/dead.err"
dead_tries=$(grep -c ' TX 07 ' "$WORK_DIR/dead.err")
jcheck monitor-dead-unit "$WORK_DIR/dead.jsonl" "
from datetime import datetime
assert len(rows) == 12, len(rows)
dead = [r['devices']['tc10@7'] for r in rows]
# A unit just tried waits at least an interval; one held may show 0 s when its retry fell due
# while the sample was being taken (a loaded machine): it is tried in the next sample.
assert all(d['status'] in ('no-reply', 'waiting') and 'no reply' in d['error'] for d in dead), dead
assert all(d['retry_in'] > 0 for d in dead if d['status'] == 'no-reply'), dead
assert all(d['retry_in'] >= 0 for d in dead if d['status'] == 'waiting'), dead
assert all(v['value'] is None and v['text'] is None for d in dead for v in d['values'].values()), dead[-1]
tries = sum(d['status'] == 'no-reply' for d in dead)
assert tries == dead[-1]['errors'] == $dead_tries and 2 <= tries <= 5, (tries, dead[-1]['errors'], $dead_tries)
for r in rows:
    for name in ('tc10@3', 'rampsoak@5'):
        assert r['devices'][name]['status'] == 'ok', r['devices'][name]
times = [datetime.fromisoformat(r['time']) for r in rows]
gaps = [(b - a).total_seconds() for a, b in zip(times, times[1:])]
# Samples start on the fixed 300 ms schedule: every gap is a whole number of slots (a sample that
# a loaded machine ran past its slot skips the slot, never bunches up) and the dead unit costs at
# most a few of the 11 slots (its 100 ms timeouts fit inside one).
slots = [round(g / 0.3) for g in gaps]
assert all(k >= 1 and abs(g - 0.3 * k) <= 0.12 for g, k in zip(gaps, slots)), gaps
assert sum(k - 1 for k in slots) <= 3, gaps
"

# The live table on a terminal: header and values drawn, Ctrl-C ends it with the cursor shown.
if $python - "$loopwire" "$link" >"$WORK_DIR/why" 2>&1 <<'PY'
import os, pty, re, select, signal, sys, time
pid, fd = pty.fork()
if pid == 0:
    os.execv(sys.argv[1], [sys.argv[1], "monitor", "--link", sys.argv[2], "--device", "tc10@3", "--interval", "200ms"])
out = b""
deadline = time.time() + 15
def read_some(until):
    global out
    while time.time() < until:
        ready, _, _ = select.select([fd], [], [], 0.1)
        if ready:
            try: chunk = os.read(fd, 4096)
            except OSError: return False
            if not chunk: return False
            out += chunk
        if until is deadline and out.count(b"sample ") >= 3: return True
    return True
read_some(deadline)
assert b"PARAMETER" in out and b"measured_value" in out and b"\x1b[?25l" in out, out[-400:]
# Later frames move back up over the 9 lines of the previous one (title, header, device, 6 values).
assert b"\x1b[9F" in out, out[-400:]
os.kill(pid, signal.SIGINT)
read_some(time.time() + 5)
_, status = os.waitpid(pid, 0)
code = os.waitstatus_to_exitcode(status)
assert code in (0, 130), code
assert out.rstrip(b"\r\n").endswith(b"\x1b[?25h"), out[-80:]
PY
then count_pass; else count_failure monitor-table-and-ctrl-c "$WORK_DIR/why"; fi

# Usage errors name the problem.
timeout 10 "$loopwire" monitor --link "$link" --device tc10@3 tc10@9:SP >"$WORK_DIR/u.out" 2>&1
if [ $? -eq 2 ] && grep -q "not one of the --device options" "$WORK_DIR/u.out"; then count_pass; else count_failure monitor-unknown-device "$WORK_DIR/u.out"; fi
timeout 10 "$loopwire" monitor --link "$link" --device tc10@3 --format table --output "$WORK_DIR/t.txt" >"$WORK_DIR/u.out" 2>&1
if [ $? -eq 2 ] && [ ! -e "$WORK_DIR/t.txt" ]; then count_pass; else count_failure monitor-table-to-file "$WORK_DIR/u.out"; fi

# Dumps: valid JSON holding every readable parameter `describe --json` lists. With a retry: on a
# loaded machine a reply may come late, and a late reply with the same bytes as another block's
# (blocks of zeros) is refused as a probable copy; the block is then asked again.
for device in tc10@3 rampsoak@5; do
  id=${device%@*}
  timeout 30 "$loopwire" describe "$id" --json >"$WORK_DIR/$id.describe.json"
  timeout 60 "$loopwire" dump --link "$link" --device "$device" --retries 1 --output "$WORK_DIR/$id.dump.json" \
    2>"$WORK_DIR/$id.dump.err" \
    || count_failure "dump $device exit status" "$WORK_DIR/$id.dump.err"
  if $python - "$WORK_DIR/$id.dump.json" "$WORK_DIR/$id.describe.json" "$id" "${device#*@}" >"$WORK_DIR/why" 2>&1 <<'PY'
import json, sys
dump = json.load(open(sys.argv[1]))
described = json.load(open(sys.argv[2]))
assert dump["format"] == "loopwire-dump" and dump["version"] == 1, dump.get("format")
assert dump["profile"] == sys.argv[3] and dump["unit"] == int(sys.argv[4])
assert dump["time"].endswith("Z") and dump["identification"], dump["identification"]
readable = [p["name"] for p in described["parameters"] if "r" in p["access"]]
assert list(dump["parameters"]) == readable, set(readable) ^ set(dump["parameters"])
for name, entry in dump["parameters"].items():
    assert set(entry) == {"value", "text", "unit", "raw", "status", "writable"}, (name, entry)
    assert len(entry["raw"]) == 1 and 0 <= entry["raw"][0] <= 0xFFFF and isinstance(entry["text"], str), (name, entry)
    assert (entry["value"] is None) == (entry["status"] not in ("ok", "unknown-label")), (name, entry)
PY
  then count_pass; else count_failure "dump-$id-matches-describe" "$WORK_DIR/why"; fi
done
if timeout 60 "$loopwire" dump --link "$tcp" --device rampsoak@5 | $python -c 'import json,sys; d=json.load(sys.stdin); assert float(d["parameters"]["set_value"]["text"]) == 425' 2>"$WORK_DIR/why"
then count_pass; else count_failure dump-to-stdout "$WORK_DIR/why"; fi

# A device that does not answer: non-zero exit, a message, and no file, temporary or final.
timeout 20 "$loopwire" dump --link "$link" --device tc10@7 --timeout 100ms --output "$WORK_DIR/unanswered.json" >"$WORK_DIR/dd.out" 2>&1
status=$?
if [ "$status" -eq 4 ] && grep -q "no reply" "$WORK_DIR/dd.out" && [ -z "$(ls "$WORK_DIR" | grep '^unanswered')" ]; then count_pass
else echo "    status $status"; count_failure dump-unanswered-leaves-no-file "$WORK_DIR/dd.out"; fi

finish
