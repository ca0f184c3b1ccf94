#!/usr/bin/env bash
# Values carry their units, as the device is configured: for every built-in profile, `read all`,
# `dump` and `monitor` against a simulated device show a unit for each value with a physical
# quantity (a number the profile does not mark "unitless"), never an empty one and never "?";
# a unit that follows a configuration word is one of those the word lists. Then the unit word
# is changed through the wire and the unit shown follows (TC10 §5.3.1 #5 unit; ramp/soak §7
# UNIT). The devices are served at the top of their manuals' address ranges (AC20 and ramp/soak
# 1-255, TC10 1-254), which simulate and --device accept.
set -u
loopwire=${1:?usage: units_test.sh path/to/loopwire}
python=/usr/bin/python3
source "$(dirname "$0")/../support/test_lib.sh"

devices=(ac20@255 tc10@254 rampsoak@250)
start_tcp_server sim.log "$loopwire" simulate --link tcp://127.0.0.1:0 \
  --device "${devices[0]}" --device "${devices[1]}" --device "${devices[2]}" --duration 100s
link="tcp://127.0.0.1:$PORT"

# Checks one output against the profile: FILE holds a JSON document, VALUES a Python expression
# giving {name: entry} with "value" and "unit" in each entry.
units_check() {  # name, describe file, output file, python expression for the values
  local name=$1 describe=$2 output=$3 values=$4
  if $python - "$describe" "$output" <<PY >"$WORK_DIR/why" 2>&1
import json, sys
profile = {p["name"]: p for p in json.load(open(sys.argv[1]))["parameters"]}
text = open(sys.argv[2]).read()
try:
    document = json.loads(text)  # one document (dump, read --json)
except json.JSONDecodeError:
    document = [json.loads(line) for line in text.splitlines() if line.strip()][-1]  # JSON lines: the last
def governing_code(rule):
    # The raw code of the word a unit follows, from its entry here: "raw", or its label.
    entry = values.get(rule["parameter"], {})
    if "raw" in entry:
        return str(entry["raw"])
    labels = profile[rule["parameter"]].get("enum", {})
    return next((code for code, label in labels.items() if label == entry.get("value")), None)
def unit_word_unlisted(p):
    # "?" is the documented unit of a value whose unit word holds a code its rules do not list
    # (TC10 Co.tY oFF: the counter counts nothing): profiles/NOTES.md, unit_from.
    return all(governing_code(rule) not in rule["units"] for rule in p["unit_from"])
values = $values
problems = []
checked = 0
for name, entry in values.items():
    p = profile[name]
    number = isinstance(entry.get("value"), (int, float)) and not isinstance(entry.get("value"), bool)
    if not number or "unitless" in p:
        continue
    checked += 1
    unit = entry.get("unit")
    if unit == "?" and "unit_from" in p and unit_word_unlisted(p):
        continue
    if not unit or unit == "?":
        problems.append(f"{name}: value {entry.get('value')} with unit {unit!r}")
    if "unit_from" in p:
        listed = {u for rule in p["unit_from"] for u in rule["units"].values()}
        if unit not in listed:
            problems.append(f"{name}: unit {unit!r} is none of {sorted(listed)}")
if checked == 0:
    problems.append("no value with a physical quantity was checked")
if problems:
    print("\n".join(problems))
    sys.exit(1)
PY
  then count_pass; else count_failure "$name" "$WORK_DIR/why" "$output"; fi
}

for device in "${devices[@]}"; do
  id=${device%@*}
  "$loopwire" describe "$id" --json >"$WORK_DIR/$id-describe.json" || fail "describe $id"
  timeout 30 "$loopwire" read --link "$link" --device "$device" all --json >"$WORK_DIR/$id-read.json" 2>"$WORK_DIR/$id-read.err"
  units_check "read-units-$id" "$WORK_DIR/$id-describe.json" "$WORK_DIR/$id-read.json" 'document["values"]'
  timeout 30 "$loopwire" dump --link "$link" --device "$device" --output "$WORK_DIR/$id-dump.json" >/dev/null 2>&1
  units_check "dump-units-$id" "$WORK_DIR/$id-describe.json" "$WORK_DIR/$id-dump.json" 'document["parameters"]'
  timeout 30 "$loopwire" monitor --link "$link" --device "$device" --count 1 --format jsonl all >"$WORK_DIR/$id-monitor.json" 2>&1
  units_check "monitor-units-$id" "$WORK_DIR/$id-describe.json" "$WORK_DIR/$id-monitor.json" \
    'next(iter(document["devices"].values()))["values"]'
done

# TC10 §5.3.1 #5 "0 = C = °C 1 = F = °F", written over the wire: the next read shows °F.
check tc10-celsius 0 "°C" "$loopwire" read --link "$link" --device tc10@254 rV
check tc10-set-fahrenheit 0 "wrote temperature_unit = F" "$loopwire" write --link "$link" --device tc10@254 temperature_unit=F
check tc10-fahrenheit 0 "°F" "$loopwire" read --link "$link" --device tc10@254 rV
check tc10-fahrenheit-monitor 0 '"unit":"°F"' "$loopwire" monitor --link "$link" --device tc10@254 --count 1 --format jsonl rV
# write shows the unit a read would: the configured one, not a fixed one.
check tc10-write-fahrenheit 0 "wrote set_point = 50 °F" "$loopwire" write --link "$link" --device tc10@254 SP=50
check tc10-write-fahrenheit-json 0 '"set_point":{"raw":50,"unit":"°F"}' \
  "$loopwire" write --link "$link" --device tc10@254 SP=50 --json
# Ramp/soak §7 UNIT "0000H=C 0001H=F 0002H=A".
check rampsoak-write-celsius 0 "wrote set_value = 60.0 °C" "$loopwire" write --link "$link" --device rampsoak@250 SV=60.0
check rampsoak-set-fahrenheit 0 "wrote unit = F" "$loopwire" write --link "$link" --device rampsoak@250 unit=F
check rampsoak-fahrenheit 0 '"unit":"°F"' "$loopwire" read --link "$link" --device rampsoak@250 PV --json
check rampsoak-write-fahrenheit 0 "wrote set_value = 140.0 °F" "$loopwire" write --link "$link" --device rampsoak@250 SV=140.0
check rampsoak-write-fahrenheit-json 0 '"set_value":{"raw":1400,"unit":"°F"}' \
  "$loopwire" write --link "$link" --device rampsoak@250 SV=140.0 --json
# A unit word written in the same command decides the unit of the values after it.
check rampsoak-write-unit-and-value 0 "wrote set_value = 60.0 °C" \
  "$loopwire" write --link "$link" --device rampsoak@250 unit=C SV=60.0

# Each manual's address limit: TC10 #131 Add "0 (oFF) ... 254" has no unit 255.
check tc10-unit-255-refused 2 "1..254" "$loopwire" read --link "$link" --device tc10@255 rV
check ac20-unit-255-answers 0 '"serial_link_address":{"value":255' "$loopwire" read --link "$link" --device ac20@255 serial_link_address --json

finish
