"""One gateway, every front: each polled value of each device is read through the HTTP API
(`/api/devices/NAME`), MQTT (the value topic and its `/meta`), the Home Assistant discovery
documents, `/metrics`, the command line (`loopwire read --json` through the gateway's Modbus TCP
front), `loopwire monitor --format csv` (its header's unit and its cell) and the public library
(tests/api/read_by_name.cpp), and all must say the same: the same text, the same unit, the same
numeric min and max, the same status.

A value can move between two fronts' reads (a simulated process runs): its text is compared only
when the API gave the same text before and after the round; its unit, limits and status always.
Fronts that lag by a poll get a few rounds to agree; the last round's disagreements are printed.

usage: cross_front_check.py LOOPWIRE READ_BY_NAME MODBUS_PORT HTTP_PORT MQTT_PORT TOKEN_FILE \
           [--expect-unit PARAMETER=UNIT]... [--expect-max PARAMETER=NUMBER]... [--write DEVICE PARAMETER=VALUE]
Exits 0 when every front agreed (and the units and limits expected are the API's).
"""
import argparse
import csv
import io
import json
import os
import subprocess
import sys
import threading
import time
import urllib.request

import paho.mqtt.client as mqtt

PREFIX = "loopwire/plant1"
DISCOVERY = "homeassistant"
# The gateway's devices (tests/gateway/cross_front_test.sh): name -> DEVICE@UNIT.
DEVICES = {"oven": "tc10@3", "furnace": "ac20@1"}
ROUNDS = 20  # rounds of reads before a disagreement is a failure (a poll or two of lag)


class Retained:
    """Every retained message under the gateway's prefix and the discovery prefix, as it stands."""

    def __init__(self, port):
        self.lock = threading.Lock()
        self.messages = {}
        self.client = mqtt.Client(client_id=f"cross-front-check-{os.getpid()}")
        self.client.on_message = self._message
        self.client.on_connect = lambda c, *_: c.subscribe([(PREFIX + "/#", 0), (DISCOVERY + "/#", 0)])
        self.client.connect("127.0.0.1", port)
        self.client.loop_start()

    def _message(self, _client, _userdata, message):
        with self.lock:
            self.messages[message.topic] = message.payload.decode("utf-8", "replace")

    def get(self, topic):
        with self.lock:
            return self.messages.get(topic)

    def discovery(self, device, parameter):
        """The discovery document whose state topic is the parameter's, with its platform."""
        state_topic = f"{PREFIX}/{device}/{parameter}"
        with self.lock:
            for topic, payload in self.messages.items():
                if topic.startswith(DISCOVERY + "/") and topic.endswith("/config") and payload:
                    doc = json.loads(payload)
                    if doc.get("state_topic") == state_topic:
                        return topic.split("/")[1], doc
        return None, None


def http_json(port, path, body=None, token=None):
    request = urllib.request.Request(f"http://127.0.0.1:{port}{path}", data=body)
    if token:
        request.add_header("Authorization", "Bearer " + token)
    with urllib.request.urlopen(request, timeout=10) as response:
        return json.loads(response.read())


def api_view(port, device):
    document = http_json(port, f"/api/devices/{device}")
    return {p["name"]: p for p in document["parameters"] if p["polled"]}


def metrics(port):
    with urllib.request.urlopen(f"http://127.0.0.1:{port}/metrics", timeout=10) as response:
        text = response.read().decode()
    values = {}
    for line in text.splitlines():
        if not line.startswith("loopwire_value{"):
            continue
        labels, number = line[len("loopwire_value{"):].rsplit("} ", 1)
        fields = dict(part.split("=", 1) for part in labels.split('",') if "=" in part)
        fields = {k: v.strip('"') for k, v in fields.items()}
        values[(fields["device"], fields["parameter"])] = (fields.get("unit", ""), float(number))
    return values


def run(command):
    done = subprocess.run(command, capture_output=True, text=True, timeout=60)
    if done.returncode != 0:
        raise RuntimeError(f"{' '.join(command)} exited {done.returncode}: {done.stderr.strip()}")
    return done.stdout


def cli_view(loopwire, link, spec, names):
    out = json.loads(run([loopwire, "read", "--json", "--timeout", "3s", "--link", link, "--device", spec, *names]))
    return out["values"]


def library_view(reader, link, spec, names):
    return {r["name"]: r for r in map(json.loads, run([reader, link, spec, *names]).splitlines())}


def monitor_view(loopwire, link, spec, names):
    """{parameter: (unit from the header, cell text)} from one CSV sample."""
    rows = list(csv.reader(io.StringIO(run([loopwire, "monitor", "--link", link, "--device", spec, "--format", "csv",
                                            "--count", "1", "--timeout", "3s", *names]))))
    view = {}
    for column, cell in zip(rows[0], rows[1]):
        if ":" not in column:
            continue
        name = column.split(":", 1)[1]
        unit = ""
        if name.endswith("]") and " [" in name:
            name, unit = name[:-1].split(" [", 1)
        view[name] = (unit, cell)
    return view


def same_number(a, b):
    if a is None or b is None:
        return a is None and b is None
    return abs(float(a) - float(b)) <= 1e-9 * max(1.0, abs(float(a)))


def compare(args, retained):
    """One round: every disagreement between the fronts, as text."""
    link = f"tcp://127.0.0.1:{args.modbus_port}"
    problems = []
    counted = 0
    prometheus = metrics(args.http_port)
    for device, spec in DEVICES.items():
        before = api_view(args.http_port, device)
        names = sorted(before)
        cli = cli_view(args.loopwire, link, spec, names)
        library = library_view(args.read_by_name, link, spec, names)
        monitor = monitor_view(args.loopwire, link, spec, names)
        after = api_view(args.http_port, device)
        for name in names:
            api = after[name]
            where = f"{device}.{name}"
            stable = before[name]["text"] == api["text"]
            unit, text, status = api["unit"], api["text"], api["status"]
            mn = api["min"] if isinstance(api["min"], (int, float)) else None
            mx = api["max"] if isinstance(api["max"], (int, float)) else None
            meta_payload = retained.get(f"{PREFIX}/{device}/{name}/meta")
            meta = json.loads(meta_payload) if meta_payload else None
            views = {
                "cli": (cli[name].get("text"), cli[name]["unit"], cli[name]["min"], cli[name]["max"], cli[name]["status"]),
                "library": (library[name]["text"], library[name]["unit"], library[name]["min"], library[name]["max"],
                            library[name]["status"]),
                "mqtt": (retained.get(f"{PREFIX}/{device}/{name}"), meta and meta["unit"], meta and meta["min"],
                         meta and meta["max"], meta and meta["status"]),
            }
            for front, (f_text, f_unit, f_min, f_max, f_status) in views.items():
                if f_unit != unit:
                    problems.append(f"{where}: unit {f_unit!r} in {front}, {unit!r} in the API")
                if not (same_number(f_min, mn) and same_number(f_max, mx)):
                    problems.append(f"{where}: limits {f_min}..{f_max} in {front}, {mn}..{mx} in the API")
                if f_status != status:
                    problems.append(f"{where}: status {f_status!r} in {front}, {status!r} in the API")
                if stable and f_text != text:
                    problems.append(f"{where}: text {f_text!r} in {front}, {text!r} in the API")
            m_unit, m_text = monitor.get(name, (None, None))
            if m_unit != unit:
                problems.append(f"{where}: unit {m_unit!r} in monitor's CSV header, {unit!r} in the API")
            if stable and m_text != text:
                problems.append(f"{where}: text {m_text!r} in monitor's CSV, {text!r} in the API")
            number = api["value"]
            if isinstance(number, (int, float)) and not isinstance(number, bool) and status == "ok":
                exported = prometheus.get((device, name))
                if exported is None:
                    problems.append(f"{where}: a polled number missing from /metrics loopwire_value")
                elif exported[0] != unit or (stable and not same_number(exported[1], number)):
                    problems.append(f"{where}: /metrics says {exported[1]} {exported[0]!r}, the API {number} {unit!r}")
            platform, doc = retained.discovery(device, name)
            if doc is not None:
                if unit and doc.get("unit_of_measurement") != unit:
                    problems.append(f"{where}: Home Assistant {platform} unit {doc.get('unit_of_measurement')!r}, {unit!r} in the API")
                # Where the device sets no limit, Home Assistant still needs numbers (its default is
                # 1..100): the number then carries what the word can hold, which is no disagreement.
                ha_min = doc.get("min") if mn is not None else None
                ha_max = doc.get("max") if mx is not None else None
                if platform == "number" and not (same_number(ha_min, mn) and same_number(ha_max, mx)):
                    problems.append(f"{where}: Home Assistant number {doc.get('min')}..{doc.get('max')}, {mn}..{mx} in the API")
            for expected in args.expect_unit:
                parameter, wanted = expected.split("=", 1)
                if parameter == name and unit != wanted:
                    problems.append(f"{where}: unit {unit!r}, expected {wanted!r}")
            for expected in args.expect_max:
                parameter, wanted = expected.split("=", 1)
                if parameter == name and not same_number(mx, float(wanted)):
                    problems.append(f"{where}: max {mx}, expected {wanted}")
            counted += 1
    return counted, problems


def main():
    parser = argparse.ArgumentParser()
    for name in ("loopwire", "read_by_name"):
        parser.add_argument(name)
    for name in ("modbus_port", "http_port", "mqtt_port"):
        parser.add_argument(name, type=int)
    parser.add_argument("token_file")
    parser.add_argument("--expect-unit", action="append", default=[])
    parser.add_argument("--expect-max", action="append", default=[])
    parser.add_argument("--write", nargs=2, metavar=("DEVICE", "PARAMETER=VALUE"))
    parser.add_argument("--write-modbus", nargs=2, metavar=("DEVICE", "PARAMETER=VALUE"),
                        help="written by a Modbus TCP client through the gateway's front (raw registers to the gateway)")
    args = parser.parse_args()
    retained = Retained(args.mqtt_port)
    if args.write:
        device, assignment = args.write
        parameter, value = assignment.split("=", 1)
        token = open(args.token_file).read().strip()
        answer = http_json(args.http_port, f"/api/devices/{device}/write", json.dumps({parameter: value}).encode(), token)
        print(f"wrote {device}.{parameter} = {value} through the HTTP API: {json.dumps(answer)}")
    if args.write_modbus:
        device, assignment = args.write_modbus
        link = f"tcp://127.0.0.1:{args.modbus_port}"
        run([args.loopwire, "write", "--timeout", "3s", "--link", link, "--device", DEVICES[device], assignment])
        print(f"wrote {device} {assignment} through the Modbus TCP front")
    problems = ["no round was made"]
    for round_number in range(1, ROUNDS + 1):
        time.sleep(1)  # the retained messages arrive; a poll after a change lands
        counted, problems = compare(args, retained)
        if not problems:
            print(f"cross-front: {counted} values agree on 7 fronts (round {round_number})")
            return 0
    print(f"cross-front: {len(problems)} disagreement(s) after {ROUNDS} rounds:")
    for problem in problems:
        print("  " + problem)
    return 1


if __name__ == "__main__":
    sys.exit(main())
