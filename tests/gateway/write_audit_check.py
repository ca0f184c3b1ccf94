#!/usr/bin/env python3
"""Writes once through every front of a running gateway and checks its audit of them.

The gateway (write_audit_test.sh) polls a simulated TC10 "oven" and a TC10 "absent" that
nothing answers for, and serves the HTTP API (with a token), MQTT, Sparkplug B and the Modbus
TCP front. Each write below waits for the oven's set point to show the value before it, so the
audit's old value is known; then GET /api/audit must hold exactly one record a write, newest
first, with the front, peer, old and new values and outcome expected; the gateway's log one
"audit:" line a record; and `loopwire audit --format json` the same records from the file.
"""
import argparse
import json
import subprocess
import sys
import time
import urllib.error
import urllib.request

from pymodbus.client import ModbusTcpClient

SET_POINT_ADDRESS = 717  # the TC10's SP: the wire address is the manual's Dec column
OVEN_UNIT = 3
DEADLINE = 30  # seconds any awaited state may take on a loaded machine


def http(port, path, body=None, token=None):
    """(status, document) of a request; a JSON body makes it a POST."""
    request = urllib.request.Request(f"http://127.0.0.1:{port}{path}",
                                     data=None if body is None else json.dumps(body).encode())
    if token:
        request.add_header("Authorization", "Bearer " + token)
    try:
        with urllib.request.urlopen(request, timeout=15) as response:
            return response.status, json.loads(response.read())
    except urllib.error.HTTPError as refused:
        return refused.code, json.loads(refused.read())


def await_true(what, predicate):
    deadline = time.monotonic() + DEADLINE
    while time.monotonic() < deadline:
        value = predicate()
        if value:
            return value
        time.sleep(0.1)
    raise SystemExit(f"FAIL: waited {DEADLINE} s for {what}")


class Checker:
    def __init__(self, args):
        self.args = args
        self.token = open(args.token_file).read().strip()
        self.expected = []  # (front, parameter, old, new, outcome prefix), oldest first
        self.problems = []
        self.decimals = 0  # the set point's, as the device's decimal point word gives them

    def text(self, value):
        """A set point as the API and the audit show it: "160.0 °C" with one decimal."""
        return f"{value:.{self.decimals}f} °C"

    def set_point(self):
        """The oven's set point as the API shows it: "160 °C" (with its decimals), or None before a poll read it."""
        _, document = http(self.args.http_port, "/api/devices/oven")
        for parameter in document["parameters"]:
            if parameter["name"] == "set_point" and parameter["status"] == "ok":
                return f"{parameter['text']} {parameter['unit']}".strip()
        return None

    def shown(self, text):
        await_true(f"the oven's set point to read {text}", lambda: self.set_point() == text)

    def expect(self, front, parameter, old, new, outcome):
        self.expected.append((front, parameter, old, new, outcome))

    def through_http(self):
        old = await_true("the oven's first poll", self.set_point)
        number = old.split(" ")[0]
        self.decimals = len(number.split(".")[1]) if "." in number else 0
        status, answer = http(self.args.http_port, "/api/devices/oven/write", {"set_point": 160}, self.token)
        if status != 200:
            self.problems.append(f"the HTTP write answered {status}: {answer}")
        self.expect("http", "set_point", old, self.text(160), "confirmed")
        self.shown(self.text(160))

    def through_mqtt(self):
        subprocess.run(["mosquitto_pub", "-p", str(self.args.mqtt_port), "-t", "loopwire/gateway/oven/set_point/set",
                        "-m", "170"], check=True, timeout=20)
        self.expect("mqtt", "set_point", self.text(160), self.text(170), "confirmed")
        self.shown(self.text(170))

    def through_sparkplug(self):
        subprocess.run([sys.executable, self.args.sparkplug_checker, "publish-dcmd", "--port", str(self.args.mqtt_port),
                        "--log", self.args.recording, "--edge", "cabinet1", "--device", "oven", "--metric", "set_point",
                        "--value", "180", "--by", "name"], check=True, timeout=30)
        self.expect("sparkplug", "set_point", self.text(170), self.text(180), "confirmed")
        self.shown(self.text(180))

    def through_modbus(self):
        client = ModbusTcpClient("127.0.0.1", port=self.args.modbus_port, timeout=5, retries=0)
        if not client.connect():
            raise SystemExit("FAIL: could not connect to the Modbus TCP front")
        raw = 190 * 10 ** self.decimals
        reply = client.write_register(SET_POINT_ADDRESS, raw, slave=OVEN_UNIT)
        client.close()
        if reply.isError():
            self.problems.append(f"the Modbus TCP write was refused: {reply}")
        # A raw write: its registers, no names and no old value; the device's configured name.
        self.expect("modbus_tcp", f"function 6 address {SET_POINT_ADDRESS} count 1", "", str(raw), "confirmed")
        self.shown(self.text(190))

    def refused_by_range(self):
        status, answer = http(self.args.http_port, "/api/devices/oven/write", {"set_point": 99999}, self.token)
        if status == 200:
            self.problems.append(f"a set point of 99999 was taken: {answer}")
        self.expect("http", "set_point", self.text(190), self.text(99999), "refused: ")

    def refused_silent(self):
        await_true("the absent device to be found silent",
                   lambda: http(self.args.http_port, "/api/devices/absent")[1].get("status") == "no-reply")
        status, answer = http(self.args.http_port, "/api/devices/absent/write", {"set_point": 100}, self.token)
        if status != 503:
            self.problems.append(f"a write to the silent device answered {status}, not 503: {answer}")
        self.expect("http", "set_point", "", "100", "refused: ")

    def compare(self, where, records):
        """The records (newest first) against what was written, oldest first."""
        got = list(reversed(records))
        if len(got) != len(self.expected):
            self.problems.append(f"{where}: {len(got)} records for {len(self.expected)} writes: {json.dumps(got, ensure_ascii=False)}")
            return
        for record, (front, parameter, old, new, outcome) in zip(got, self.expected):
            device = "absent" if record["device"] == "absent" else "oven"
            wanted = {"front": front, "parameter": parameter, "old_value": old, "new_value": new, "device": device}
            for field, value in wanted.items():
                if record[field] != value:
                    self.problems.append(f"{where}: {field} is {record[field]!r}, expected {value!r} in {record}")
            if not record["outcome"].startswith(outcome) or (outcome == "confirmed" and record["outcome"] != outcome):
                self.problems.append(f"{where}: outcome {record['outcome']!r}, expected {outcome!r}… in {record}")
            if front in ("http", "modbus_tcp") and not record["peer"].startswith("127.0.0.1"):
                self.problems.append(f"{where}: peer {record['peer']!r}, expected the client's 127.0.0.1 in {record}")
            if front in ("mqtt", "sparkplug") and record["peer"] != "broker":
                self.problems.append(f"{where}: peer {record['peer']!r}, expected \"broker\" in {record}")

    def audited(self):
        status, document = http(self.args.http_port, "/api/audit?from=-1h", token=None)
        if status != 200:
            return None
        return document["records"] if len(document["records"]) >= len(self.expected) else None

    def run(self):
        for step in (self.through_http, self.through_mqtt, self.through_sparkplug, self.through_modbus,
                     self.refused_by_range, self.refused_silent):
            step()
        # The store commits every 0.5 s: the rows come a moment after the writes' answers.
        records = await_true(f"{len(self.expected)} records in GET /api/audit", self.audited)
        self.compare("GET /api/audit", records)
        _, only_absent = http(self.args.http_port, "/api/audit?device=absent&limit=5")
        if [r["device"] for r in only_absent["records"]] != ["absent"]:
            self.problems.append(f"GET /api/audit?device=absent: {only_absent}")
        cli = subprocess.run([self.args.loopwire, "audit", "--database", self.args.database, "--from", "-1h", "--format",
                              "json"], capture_output=True, text=True, timeout=30)
        if cli.returncode != 0:
            self.problems.append(f"loopwire audit exited {cli.returncode}: {cli.stderr}")
        else:
            self.compare("loopwire audit", json.loads(cli.stdout)["records"])
        lines = [line for line in open(self.args.gateway_log, encoding="utf-8") if "audit: " in line]
        if len(lines) != len(self.expected):
            self.problems.append(f"the log has {len(lines)} audit lines for {len(self.expected)} writes: {lines}")
        counts = {}
        for record in records:
            counts[record["front"]] = counts.get(record["front"], 0) + 1
        print("audit records by front:", json.dumps(counts))
        for record in records:
            print("  ", json.dumps(record, ensure_ascii=False))
        for line in lines:
            print("  log:", line.rstrip())
        for problem in self.problems:
            print("FAIL:", problem)
        return 1 if self.problems else 0


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    for name in ("loopwire", "http_port", "modbus_port", "mqtt_port", "token_file", "database", "gateway_log", "recording",
                 "sparkplug_checker"):
        parser.add_argument(name, type=int if name.endswith("_port") else str)
    return Checker(parser.parse_args()).run()


if __name__ == "__main__":
    sys.exit(main())
