#!/usr/bin/python3
"""An independent Sparkplug B 3.0 observer for the gateway's [sparkplug] edge node.

The gateway's own code is not trusted here: every message is decoded with a protobuf module
that protoc generates from the repository's .proto (only the wire format is shared), and the
Sparkplug rules are checked from what a host application would see on the broker.

Subcommands (all take the recording, a file of JSON lines, as written by `record`):
  record        subscribe to spBv1.0/# and append one decoded JSON line per message
  wait          wait until a message matching a filter is recorded (prints "line N ...")
  count         how many recorded messages match a filter
  value         one field of a recorded message (a metric's value, alias, property, seq...)
  expect-metrics  assert a birth's (or data message's) metrics: datatype, value, properties
  show          print messages in a readable form, data metrics named from their births
  check         replay the whole recording against the Sparkplug rules; print every failure
                (a historical metric, store and forward's, is a value of the past: never taken
                for the current one, and each metric's come in their order)
  historical    store and forward's figures after a line: historical values, duplicates, order
  series        every value of one device's metric, live and historical, for a comparison
  publish-ncmd, publish-dcmd, publish-state   encode and publish what a host would send
  flap-state    publish the host's STATE online and offline in turn, quickly, ending online
  selftest      round-trip payloads through the proto and prove `check` catches each rule

The generated module is imported from --pb DIR or $SPARKPLUG_PB_DIR; without either, protoc
is run into a temporary directory on the repository's proto.
"""

import argparse
import json
import os
import subprocess
import sys
import tempfile
import threading
import time

NAMESPACE = "spBv1.0"
NODE_MESSAGES = {"NBIRTH", "NDEATH", "NDATA", "NCMD"}
DEVICE_MESSAGES = {"DBIRTH", "DDEATH", "DDATA", "DCMD"}
# Messages of the node that carry the node's seq (NBIRTH too, with 0; NDEATH never).
SEQ_MESSAGES = {"NDATA", "DBIRTH", "DDATA", "DDEATH"}
FROM_NODE = {"NBIRTH", "NDEATH", "NDATA", "DBIRTH", "DDEATH", "DDATA"}

# Sparkplug 3.0 data type codes (specification 6.4.16) and the Metric/PropertyValue field that
# carries each.
DATATYPE_NAMES = {
    1: "Int8", 2: "Int16", 3: "Int32", 4: "Int64", 5: "UInt8", 6: "UInt16", 7: "UInt32",
    8: "UInt64", 9: "Float", 10: "Double", 11: "Boolean", 12: "String", 13: "DateTime",
    14: "Text", 15: "UUID", 16: "DataSet", 17: "Bytes", 18: "File", 19: "Template",
    20: "PropertySet", 21: "PropertySetList",
}
VALUE_FIELD = {
    1: "int_value", 2: "int_value", 3: "int_value", 5: "int_value", 6: "int_value", 7: "int_value",
    4: "long_value", 8: "long_value", 13: "long_value",
    9: "float_value", 10: "double_value", 11: "boolean_value",
    12: "string_value", 14: "string_value", 15: "string_value",
    17: "bytes_value", 18: "bytes_value", 20: "propertyset_value",
}
SIGNED_BITS = {1: 8, 2: 16, 3: 32, 4: 64}
UNSIGNED_BITS = {5: 8, 6: 16, 7: 32, 8: 64, 13: 64}
# The datatypes the contract lets the gateway give a metric.
GATEWAY_DATATYPES = {2, 3, 6, 8, 10, 11, 12}

# The metric properties of the contract and the datatype each must have.
PROPERTY_TYPES = {
    "engUnit": 12, "engLow": 10, "engHigh": 10, "decimals": 3,
    "writable": 11, "readOnly": 11, "mnemonic": 12, "Quality": 3, "documentation": 12,
}
QUALITY_GOOD, QUALITY_STALE, QUALITY_BAD = 192, 500, 0
QUALITIES = {QUALITY_GOOD: "good", QUALITY_STALE: "stale", QUALITY_BAD: "bad"}

BDSEQ = "bdSeq"
REBIRTH = "Node Control/Rebirth"
LAST_ERROR = "Device Control/Last Error"

# A timestamp further than this from the moment the recorder received its message is a wrong
# clock or a wrong unit (seconds or microseconds instead of milliseconds). Generous: a loaded
# machine running a sanitized gateway can hold a message for seconds.
TIMESTAMP_PAST_MS = 120_000
TIMESTAMP_FUTURE_MS = 5_000
# A historical metric (store and forward) carries the time of its sample, from before the
# outage it was kept through: as old as the node's store_and_forward, never from the future.
HISTORICAL_PAST_MS = 7 * 24 * 3600 * 1000


# --- The generated protobuf module --------------------------------------------------------------

_pb2 = None


def pb2(pb_dir=None):
    """The protoc-generated module, imported once."""
    global _pb2
    if _pb2 is not None:
        return _pb2
    pb_dir = pb_dir or os.environ.get("SPARKPLUG_PB_DIR")
    if not pb_dir:
        # Standalone use: compile the repository's proto, as the shell test does.
        here = os.path.dirname(os.path.abspath(__file__))
        proto_dir = os.path.normpath(os.path.join(here, "..", "..", "src", "gateway", "sparkplug"))
        pb_dir = tempfile.mkdtemp(prefix="sparkplug-pb-")
        subprocess.run(["protoc", f"--python_out={pb_dir}", "-I", proto_dir,
                        os.path.join(proto_dir, "sparkplug_b.proto")], check=True)
    sys.path.insert(0, pb_dir)
    import sparkplug_b_pb2  # noqa: E402  (generated at run time)
    _pb2 = sparkplug_b_pb2
    return _pb2


# --- Transcription: one MQTT message to one JSON record ------------------------------------------
# The record holds what was on the wire and nothing inferred: a field absent on the wire is a
# key absent from the record, so the rules can tell "not sent" from "sent empty".

def _raw(field, value):
    if field == "bytes_value":
        return value.hex()
    return value


def transcribe_property_set(ps):
    if len(ps.keys) != len(ps.values):
        return {"error": f"{len(ps.keys)} keys but {len(ps.values)} values",
                "keys": list(ps.keys)}
    pairs = []
    for key, pv in zip(ps.keys, ps.values):
        entry = {}
        if pv.HasField("type"):
            entry["type"] = pv.type
        if pv.HasField("is_null"):
            entry["is_null"] = pv.is_null
        field = pv.WhichOneof("value")
        if field == "propertyset_value":
            entry["field"] = field
            entry["value"] = transcribe_property_set(pv.propertyset_value)
        elif field is not None:
            entry["field"] = field
            entry["value"] = _raw(field, getattr(pv, field))
        pairs.append([key, entry])
    return pairs


def transcribe_metric(m):
    out = {}
    for key in ("name", "alias", "timestamp", "datatype", "is_historical", "is_transient", "is_null"):
        if m.HasField(key):
            out[key] = getattr(m, key)
    if m.HasField("properties"):
        out["properties"] = transcribe_property_set(m.properties)
    field = m.WhichOneof("value")
    if field is not None:
        out["field"] = field
        out["value"] = _raw(field, getattr(m, field))
    return out


def transcribe(topic, payload, qos, retain, received_ms):
    rec = {"t": received_ms, "topic": topic, "qos": qos, "retain": bool(retain), "bytes": len(payload)}
    parts = topic.split("/")
    if parts[0] != NAMESPACE or len(parts) < 3:
        rec["type"] = "OTHER"
        rec["error"] = f"not a Sparkplug B topic ({NAMESPACE}/GROUP/TYPE/EDGE[/DEVICE])"
        return rec
    if parts[1] == "STATE":
        rec["type"] = "STATE"
        rec["host"] = parts[2]
        if len(parts) != 3:
            rec["error"] = "a STATE topic is spBv1.0/STATE/HOST"
        try:
            rec["state"] = json.loads(payload.decode("utf-8"))
        except (UnicodeDecodeError, ValueError) as e:
            rec["error"] = f"STATE payload is not JSON: {e}"
            rec["hex"] = payload.hex()
        return rec
    rec["group"], rec["type"] = parts[1], parts[2]
    rec["edge"] = parts[3] if len(parts) > 3 else None
    rec["device"] = parts[4] if len(parts) > 4 else None
    want = 5 if rec["type"] in DEVICE_MESSAGES else 4
    if rec["type"] not in NODE_MESSAGES | DEVICE_MESSAGES:
        rec["error"] = f"unknown message type {rec['type']!r}"
    elif len(parts) != want:
        rec["error"] = f"a {rec['type']} topic has {want} levels, this one {len(parts)}"
    rec["hex"] = payload.hex()
    p = pb2().Payload()
    try:
        p.ParseFromString(payload)
    except Exception as e:  # DecodeError, or anything else the runtime raises on garbage
        rec["error"] = f"payload is not a Sparkplug B Payload: {e}"
        return rec
    rec["seq"] = p.seq if p.HasField("seq") else None
    rec["timestamp"] = p.timestamp if p.HasField("timestamp") else None
    if p.HasField("uuid"):
        rec["uuid"] = p.uuid
    if p.HasField("body"):
        rec["body"] = p.body.hex()
    rec["metrics"] = [transcribe_metric(m) for m in p.metrics]
    return rec


# --- Encoding: what a host sends ------------------------------------------------------------------

def set_value(target, datatype, value):
    """Puts VALUE (a Python value or the text given on the command line) in the field of
    TARGET (a Metric or PropertyValue) that DATATYPE uses."""
    field = VALUE_FIELD.get(datatype)
    if field is None:
        raise ValueError(f"cannot encode datatype {datatype}")
    if field in ("int_value", "long_value"):
        number = int(value) if not isinstance(value, str) else int(value, 0)
        width = 32 if field == "int_value" else 64
        setattr(target, field, number & ((1 << width) - 1))  # two's complement, as the spec says
    elif field in ("float_value", "double_value"):
        setattr(target, field, float(value))
    elif field == "boolean_value":
        if isinstance(value, str):
            if value.lower() not in ("true", "false", "1", "0"):
                raise ValueError(f"{value!r} is not a Boolean (true or false)")
            value = value.lower() in ("true", "1")
        target.boolean_value = bool(value)
    elif field == "string_value":
        target.string_value = str(value)
    elif field == "bytes_value":
        target.bytes_value = bytes.fromhex(value) if isinstance(value, str) else bytes(value)
    else:
        raise ValueError(f"cannot encode datatype {datatype}")


def build_payload(seq=None, timestamp=None, metrics=()):
    """A Payload from plain descriptions: each metric a dict with name, alias, datatype, value,
    is_null, timestamp, props ([(key, datatype, value)]), raw_field/raw_value (to put a value in
    a field its datatype does not use, for the self-test's broken messages)."""
    p = pb2().Payload()
    if timestamp is not None:
        p.timestamp = timestamp
    if seq is not None:
        p.seq = seq
    for spec in metrics:
        m = p.metrics.add()
        for key in ("name", "alias", "timestamp", "datatype", "is_null", "is_historical"):
            if spec.get(key) is not None:
                setattr(m, key, spec[key])
        if "raw_field" in spec:
            setattr(m, spec["raw_field"], spec["raw_value"])
        elif spec.get("value") is not None:
            set_value(m, spec.get("value_type", spec.get("datatype")), spec["value"])
        for key, datatype, value in spec.get("props", ()):
            m.properties.keys.append(key)
            pv = m.properties.values.add()
            pv.type = datatype
            if value is None:
                pv.is_null = True
            else:
                set_value(pv, datatype, value)
    return p


def now_ms():
    return int(time.time() * 1000)


# --- Reading a recording --------------------------------------------------------------------------

class Recording:
    """Reads a recording as it grows. A last line without its newline is being written: it is
    left for the next read."""

    def __init__(self, path):
        self.path = path
        self.offset = 0
        self.pending = b""

    def new_records(self):
        try:
            with open(self.path, "rb") as f:
                f.seek(self.offset)
                data = f.read()
        except FileNotFoundError:
            return []
        self.offset += len(data)
        data = self.pending + data
        lines = data.split(b"\n")
        self.pending = lines.pop()
        return [json.loads(line) for line in lines if line.strip()]


def load(path):
    return Recording(path).new_records()


# --- The rules -------------------------------------------------------------------------------------

def dt_name(datatype):
    return DATATYPE_NAMES.get(datatype, f"datatype {datatype}")


def interpret(field, raw, datatype, problems):
    """The value a host reads from FIELD/RAW under DATATYPE; wrong fields and out-of-range
    integers are added to PROBLEMS."""
    if field is None:
        return None
    if datatype is None:
        return raw  # an alias no birth names: that is reported once, as such
    want = VALUE_FIELD.get(datatype)
    if want is None:
        problems.append(f"{dt_name(datatype)} is not a datatype with a value field")
        return raw
    if field != want:
        problems.append(f"value in {field} ({raw!r}), but {dt_name(datatype)} is carried in {want}")
        return raw
    if datatype in SIGNED_BITS:
        width = 32 if field == "int_value" else 64
        value = raw - (1 << width) if raw >= 1 << (width - 1) else raw
        bits = SIGNED_BITS[datatype]
        if not -(1 << (bits - 1)) <= value < 1 << (bits - 1):
            problems.append(
                f"{field} {raw} is {value} as {width}-bit two's complement, outside {dt_name(datatype)} "
                f"(a negative {dt_name(datatype)} is sign-extended to {width} bits)")
        return value
    if datatype in UNSIGNED_BITS:
        if raw >= 1 << UNSIGNED_BITS[datatype]:
            problems.append(f"{field} {raw} is outside {dt_name(datatype)}")
        return raw
    return raw


def read_properties(metric, problems, notes):
    """The metric's properties as {key: value} (None for a null one); malformed ones go to
    PROBLEMS, keys outside the contract to NOTES."""
    props = {}
    pairs = metric.get("properties")
    if pairs is None:
        return props
    if isinstance(pairs, dict):
        problems.append(f"PropertySet malformed: {pairs.get('error')}")
        return props
    for key, pv in pairs:
        if key in props:
            problems.append(f"property {key!r} appears twice")
        want = PROPERTY_TYPES.get(key)
        datatype = pv.get("type")
        if want is None:
            notes.append(f"property {key!r} is not one of the contract's")
        elif datatype != want:
            problems.append(f"property {key!r} has type {dt_name(datatype)}, the contract says {dt_name(want)}")
        if pv.get("is_null"):
            if "field" in pv:
                problems.append(f"property {key!r} is null yet carries {pv['field']}")
            props[key] = None
            continue
        if "field" not in pv:
            problems.append(f"property {key!r} has neither a value nor is_null")
            props[key] = None
            continue
        sub = []
        props[key] = interpret(pv["field"], pv["value"], datatype, sub)
        problems.extend(f"property {key!r}: {s}" for s in sub)
    quality = props.get("Quality")
    if "Quality" in props and quality not in QUALITIES:
        problems.append(f"Quality {quality!r} is none of 192 (good), 500 (stale), 0 (bad)")
    return props


class MetricInfo:
    def __init__(self, name, alias, datatype, line):
        self.name, self.alias, self.datatype, self.line = name, alias, datatype, line


class Device:
    def __init__(self, name):
        self.name = name
        self.born = False
        self.birth_line = None
        self.metrics = {}   # alias -> MetricInfo, from the current DBIRTH
        self.last = {}      # alias -> (is_null, value, quality) last reported
        self.values = {}    # name -> last value reported (for `value --latest`)
        self.historical = {}  # alias -> timestamp of the last historical value, since the birth


class Node:
    def __init__(self, group, edge):
        self.group, self.edge = group, edge
        self.born = False
        self.last_event = None          # "NBIRTH" or "NDEATH": what the connection did last
        self.bdseq = None               # the current connection's, from its NBIRTH
        self.birth_line = None
        self.last_death_bdseq = None
        self.last_death_line = self.last_death_timestamp = None
        self.seq = None
        self.seq_line = None
        self.seq_messages = 0           # since the last NBIRTH
        self.wraps = 0
        self.metrics = {}               # alias -> MetricInfo of the current NBIRTH
        self.last = {}
        self.values = {}
        self.devices = {}
        self.registry = {}              # alias -> (device or "", name) within this process
        self.aliases = {}               # (device or "", name) -> (alias, line)
        self.processes = 0
        self.counts = {}
        self.bdseqs = []
        self.restart_line = None        # the last broker restart the recorder saw (a BROKER record)

    def device(self, name):
        if name not in self.devices:
            self.devices[name] = Device(name)
        return self.devices[name]


class Model:
    """Replays a recording, message by message, against the Sparkplug rules. Each record gets
    "_resolved" (its metrics with the names, datatypes and values a host would read) and
    "_wrap" (its seq went 255 -> 0)."""

    def __init__(self):
        self.nodes = {}
        self.failures = []   # (rule, line, text)
        self.notes = []
        self.messages = 0
        self.hosts = {}

    def node_of(self, rec):
        key = (rec.get("group"), rec.get("edge"))
        if key not in self.nodes:
            self.nodes[key] = Node(*key)
        return self.nodes[key]

    def fail(self, rule, rec, text):
        where = rec["topic"]
        self.failures.append((rule, rec.get("line"), f"[{rule}] line {rec.get('line')} {rec.get('type')} {where}: {text}"))

    def note(self, rec, text, metric=None):
        where = f"line {rec.get('line')} {rec.get('type')} {rec['topic']}" + (f" {metric}" if metric else "")
        self.notes.append((where, text))

    # -- per message --

    def feed(self, rec):
        self.messages += 1
        rec["_resolved"] = []
        kind = rec.get("type")
        if rec.get("error"):
            self.fail("decode", rec, rec["error"])
        if kind == "STATE":
            self.on_state(rec)
            return
        if kind == "BROKER":
            self.on_broker_restart(rec)
            return
        if kind not in NODE_MESSAGES | DEVICE_MESSAGES or "metrics" not in rec:
            if not rec.get("error"):
                self.fail("topic", rec, "not a Sparkplug message this observer knows")
            return
        node = self.node_of(rec)
        node.counts[kind] = node.counts.get(kind, 0) + 1
        if kind in ("NCMD", "DCMD"):
            return  # the host's (this test's) own commands: recorded as evidence, not judged
        if rec.get("retain"):
            self.fail("retained", rec, "published retained; only the host's STATE may be")
        self.check_timestamp(rec, rec.get("timestamp"), "payload",
                             required=kind != "NDEATH")
        getattr(self, "on_" + kind.lower())(node, rec)

    def check_timestamp(self, rec, ts, what, required=True):
        if ts is None:
            if required:
                self.fail("timestamp", rec, f"no {what} timestamp")
            return
        if not rec["t"] - TIMESTAMP_PAST_MS <= ts <= rec["t"] + TIMESTAMP_FUTURE_MS:
            self.fail("timestamp", rec, f"{what} timestamp {ts} is {(ts - rec['t']) / 1000:+.1f} s from the "
                      "time it was received (not ms since the epoch, UTC?)")

    def check_seq(self, node, rec):
        seq = rec.get("seq")
        node.seq_messages += 1
        if seq is None:
            self.fail("seq", rec, "no seq")
            return
        if not 0 <= seq <= 255:
            self.fail("seq", rec, f"seq {seq} is outside 0..255")
        elif node.seq is not None:
            expected = (node.seq + 1) % 256
            if seq != expected:
                self.fail("seq", rec, f"seq {seq}, expected {expected} (line {node.seq_line} had seq {node.seq})")
            elif seq == 0:
                node.wraps += 1
                rec["_wrap"] = True
        node.seq, node.seq_line = seq, rec["line"]

    def check_alias(self, node, device, info, rec):
        """Aliases are unique within the node (node and all devices) and stable for a name
        within one process of the node."""
        key = (device or "", info.name)
        owner = node.registry.get(info.alias)
        if owner is not None and owner != key:
            self.fail("alias-unique", rec, f"alias {info.alias} of {describe_key(key)} is already that of "
                      f"{describe_key(owner)}")
        before = node.aliases.get(key)
        if before is not None and before[0] != info.alias:
            self.fail("alias-stable", rec, f"{describe_key(key)} has alias {info.alias}; its birth at line "
                      f"{before[1]} gave alias {before[0]} (aliases must not change across rebirths)")
        node.registry[info.alias] = key
        if before is None or before[0] != info.alias:
            node.aliases[key] = (info.alias, rec["line"])

    def read_metric(self, rec, m, datatype, problems, notes):
        """Value, is_null and quality of M under DATATYPE, with the null/quality rules."""
        props = read_properties(m, problems, notes)
        value = interpret(m.get("field"), m.get("value"), datatype, problems)
        is_null = bool(m.get("is_null"))
        quality = props.get("Quality")
        if is_null and "field" in m:
            problems.append(f"is_null yet carries {m['field']} {m['value']!r} (no value may be sent for a null)")
        if not is_null and "field" not in m:
            problems.append("neither a value nor is_null")
        if rec["type"] in ("DBIRTH", "DDATA"):
            if is_null and quality not in (QUALITY_STALE, QUALITY_BAD):
                problems.append(f"is_null without a Quality of 500 (stale) or 0 (bad): Quality {quality!r}")
            if not is_null and quality in (QUALITY_STALE, QUALITY_BAD):
                problems.append(f"a number ({value!r}) sent with Quality {quality} ({QUALITIES[quality]}); a "
                                "missing or stale value is sent as is_null")
        effective = quality if quality is not None else (None if is_null else QUALITY_GOOD)
        return value, is_null, effective, props

    def birth_metrics(self, node, device, rec):
        """The metrics of an NBIRTH (DEVICE None) or DBIRTH, checked and registered."""
        infos, last, values = {}, {}, {}
        names = set()
        for i, m in enumerate(rec["metrics"]):
            problems, notes = [], []
            label = repr(m.get("name", f"metric #{i}"))
            for key in ("name", "alias", "datatype"):
                if key not in m:
                    problems.append(f"no {key}")
            if rec["type"] == "DBIRTH" and "timestamp" not in m:
                problems.append("no timestamp")
            elif "timestamp" in m:
                self.check_timestamp(rec, m["timestamp"], f"metric {label}")
            datatype = m.get("datatype")
            if datatype is not None and datatype not in GATEWAY_DATATYPES:
                problems.append(f"{dt_name(datatype)} is none of the contract's datatypes")
            value, is_null, quality, props = self.read_metric(rec, m, datatype, problems, notes)
            for p in problems:
                self.fail("metric", rec, f"{label}: {p}")
            for n in notes:
                self.note(rec, n, metric=label)
            rec["_resolved"].append(resolved(m.get("name"), m.get("alias"), datatype, value, is_null, quality, props))
            if "name" not in m or "alias" not in m:
                continue
            if m["name"] in names:
                self.fail("birth", rec, f"{label} appears twice")
            names.add(m["name"])
            info = MetricInfo(m["name"], m["alias"], datatype, rec["line"])
            if m["alias"] in infos:
                self.fail("alias-unique", rec, f"alias {m['alias']} is given to {infos[m['alias']].name!r} and {label}")
            self.check_alias(node, device, info, rec)
            infos[m["alias"]] = info
            last[m["alias"]] = (is_null, value, quality)
            values[m["name"]] = None if is_null else value
        return infos, last, values

    def data_metrics(self, owner, rec, alias_only):
        """The metrics of an NDATA or DDATA, each named by an alias of OWNER's birth."""
        if not rec["metrics"]:
            self.fail("data-empty", rec, "a data message without metrics")
        seen = set()
        for i, m in enumerate(rec["metrics"]):
            problems, notes = [], []
            alias = m.get("alias")
            info = owner.metrics.get(alias) if alias is not None else None
            label = f"alias {alias}" + (f" ({info.name!r})" if info else "")
            if alias is None:
                problems.append(f"metric #{i} ({m.get('name')!r}) has no alias")
            elif info is None:
                problems.append(f"alias {alias} is not one of the current birth's ({self.owner_of(rec, alias)})")
            if "name" in m:
                if alias_only:
                    problems.append(f"carries a name ({m['name']!r}); data names metrics by alias only")
                elif info and m["name"] != info.name:
                    problems.append(f"name {m['name']!r} is not its alias's {info.name!r}")
            if alias in seen:
                problems.append("reported twice in one message")
            seen.add(alias)
            historical = bool(m.get("is_historical"))
            if "timestamp" not in m:
                problems.append("no timestamp")
            elif historical:
                if not rec["t"] - HISTORICAL_PAST_MS <= m["timestamp"] <= rec["t"] + TIMESTAMP_FUTURE_MS:
                    problems.append(f"historical timestamp {m['timestamp']} is not of the past week")
                before = getattr(owner, "historical", {}).get(alias)
                if before is not None and m["timestamp"] <= before:
                    problems.append(f"historical value of {m['timestamp']} after one of {before}: store and forward "
                                    "sends a metric's values in their order, each once")
            else:
                self.check_timestamp(rec, m["timestamp"], f"metric {label}")
            datatype = info.datatype if info else m.get("datatype")
            if info and "datatype" in m and m["datatype"] != info.datatype:
                problems.append(f"datatype {dt_name(m['datatype'])}, born as {dt_name(info.datatype)}")
            value, is_null, quality, props = self.read_metric(rec, m, datatype, problems, notes)
            rec["_resolved"].append(resolved(info.name if info else m.get("name"), alias, datatype, value,
                                             is_null, quality, props))
            if info is not None and historical:
                # A value of the past: recorded by a host, never taken for the current one, so it
                # is judged neither against the last report nor as the next to compare with.
                if hasattr(owner, "historical") and "timestamp" in m:
                    owner.historical[alias] = m["timestamp"]
            elif info is not None:
                state = (is_null, value, quality)
                if owner.last.get(alias) == state:
                    text = (f"repeated unchanged: value {value!r}, is_null {is_null}, Quality {quality}, "
                            "as last reported")
                    if rec["type"] == "DDATA":
                        problems.append(text + " (data carries only changes)")
                    else:
                        notes.append(f"{label}: {text}")
                owner.last[alias] = state
                owner.values[info.name] = None if is_null else value
            for p in problems:
                self.fail("data", rec, f"{label}: {p}")
            for n in notes:
                self.note(rec, n)

    def owner_of(self, rec, alias):
        node = self.node_of(rec)
        key = node.registry.get(alias)
        return f"it belongs to {describe_key(key)}" if key else "unknown to the node"

    # -- per type --

    def on_nbirth(self, node, rec):
        metrics = {m.get("name"): m for m in rec["metrics"] if "name" in m}
        if rec.get("device"):
            self.fail("topic", rec, "an NBIRTH topic names no device")
        if rec.get("seq") != 0:
            self.fail("seq", rec, f"NBIRTH seq {rec.get('seq')}, must be 0")
        bdseq = None
        m = metrics.get(BDSEQ)
        if m is None:
            self.fail("bdseq", rec, "NBIRTH without a bdSeq metric")
        elif m.get("datatype") != 8 or m.get("field") != "long_value":
            self.fail("bdseq", rec, f"bdSeq is {dt_name(m.get('datatype'))} in {m.get('field')}, must be UInt64 in long_value")
        else:
            bdseq = m["value"]
        rb = metrics.get(REBIRTH)
        if rb is None:
            self.fail("nbirth", rec, f"no {REBIRTH!r} metric")
        elif rb.get("datatype") != 11 or rb.get("field") != "boolean_value" or rb.get("value") is not False:
            self.fail("nbirth", rec, f"{REBIRTH!r} must be Boolean false: datatype {rb.get('datatype')}, "
                      f"{rb.get('field')} {rb.get('value')!r}")
        lines = {}
        for name, metric in metrics.items():
            parts = name.split("/")
            if len(parts) == 3 and parts[0] == "Lines":
                lines.setdefault(parts[1], {})[parts[2]] = metric.get("datatype")
        for line, stats in lines.items():
            for stat, want in (("Requests", 8), ("Answered", 8), ("Timeouts", 8), ("Open", 11)):
                if stats.get(stat) != want:
                    self.fail("nbirth", rec, f"Lines/{line}/{stat}: datatype {stats.get(stat)}, must be {dt_name(want)}")

        # bdSeq across connections and processes.
        if bdseq is not None:
            if node.last_event is None:
                if bdseq != 0:
                    self.fail("bdseq", rec, f"the node's first NBIRTH in the recording has bdSeq {bdseq}; "
                              "a new process starts at 0")
                self.new_process(node)
            elif node.last_event == "NBIRTH":
                if bdseq != node.bdseq:
                    self.fail("bdseq", rec, f"rebirth on the same connection with bdSeq {bdseq}; the NBIRTH "
                              f"at line {node.birth_line} had {node.bdseq}")
            else:
                previous = node.last_death_bdseq
                if previous is not None and bdseq == (previous + 1) % 256:
                    pass  # the same process on a new connection
                elif node.restart_line and node.restart_line > (node.birth_line or 0) and bdseq != previous:
                    # After a broker restart: the attempts the node made while no broker was
                    # there are not seen, and a process started meanwhile counts on from its
                    # state file; only the lost connection's bdSeq may not be born again.
                    pass
                elif bdseq == 0:
                    self.new_process(node)
                else:
                    self.fail("bdseq", rec, f"bdSeq {bdseq} after an NDEATH with bdSeq {previous}: expected "
                              f"{None if previous is None else (previous + 1) % 256} (a new connection) or 0 "
                              "(a new process)")
            node.bdseq = bdseq
            node.bdseqs.append(bdseq)
        node.born = True
        node.last_event = "NBIRTH"
        node.birth_line = rec["line"]
        node.seq, node.seq_line, node.seq_messages = 0, rec["line"], 0
        for device in node.devices.values():
            device.born = False  # every device is born again after its node
        node.metrics, node.last, node.values = self.birth_metrics(node, None, rec)

    def on_broker_restart(self, rec):
        """The recorder connected again: the broker was restarted, every node's connection ended
        without an NDEATH (the will went with the old broker) and its devices are dead."""
        self.note(rec, "the broker was restarted: every node's connection ended (its will went with the old "
                       "broker, or it published it as it stopped)")
        for node in self.nodes.values():
            node.restart_line = rec["line"]
            if node.last_event == "NBIRTH":
                node.last_event = "LOST"
                node.last_death_bdseq = node.bdseq
            node.born = False
            for device in node.devices.values():
                device.born = False

    def new_process(self, node):
        node.registry, node.aliases = {}, {}
        node.processes += 1

    def on_ndeath(self, node, rec):
        if rec.get("device"):
            self.fail("topic", rec, "an NDEATH topic names no device")
        if rec.get("seq") is not None:
            self.fail("ndeath", rec, f"NDEATH carries seq {rec['seq']}; it has none")
        ms = rec["metrics"]
        if len(ms) != 1 or ms[0].get("name") != BDSEQ:
            self.fail("ndeath", rec, f"NDEATH metrics {[m.get('name') for m in ms]}; must be bdSeq alone")
        bdseq = None
        for m in ms:
            if m.get("name") == BDSEQ:
                if m.get("datatype") != 8 or m.get("field") != "long_value":
                    self.fail("ndeath", rec, f"bdSeq is {dt_name(m.get('datatype'))} in {m.get('field')}, must be UInt64 in long_value")
                bdseq = m.get("value")
                rec["_resolved"].append(resolved(BDSEQ, m.get("alias"), 8, bdseq, False, None, {}))
        if rec.get("qos") != 1:
            self.note(rec, f"NDEATH delivered with QoS {rec.get('qos')} (Sparkplug: the will is QoS 1)")
        if node.last_event == "NBIRTH":
            if bdseq != node.bdseq:
                self.fail("bdseq", rec, f"NDEATH bdSeq {bdseq}, but the NBIRTH of this connection (line "
                          f"{node.birth_line}) had bdSeq {node.bdseq}")
        elif node.last_event == "NDEATH":
            previous = node.last_death_bdseq
            if bdseq == previous and rec.get("timestamp") == node.last_death_timestamp and node.restart_line and \
                    node.last_death_line < node.restart_line:
                # The will the old broker published as it stopped, delivered again by the new one
                # from the observer's persisted session: the broker's redelivery, not the node's.
                self.note(rec, f"NDEATH (bdSeq {bdseq}) of line {node.last_death_line} delivered again after "
                               "the broker's restart")
            elif bdseq == previous:
                # The timestamps tell a resent NDEATH (the same one) from the broker's will (made
                # at connect, older).
                self.fail("bdseq", rec, f"a second NDEATH with bdSeq {bdseq} and no NBIRTH between: this one's "
                          f"timestamp {rec.get('timestamp')}, the one at line {node.last_death_line} had "
                          f"{node.last_death_timestamp} (one connection's death delivered twice)")
            elif previous is not None and bdseq not in ((previous + 1) % 256, 0):
                self.fail("bdseq", rec, f"NDEATH bdSeq {bdseq} after an NDEATH with {previous} and no NBIRTH")
            else:
                self.note(rec, f"NDEATH of a connection that never sent NBIRTH (bdSeq {bdseq})")
        else:
            self.note(rec, "NDEATH of a node never born in this recording")
        node.born = False
        node.last_event = "NDEATH"
        node.last_death_bdseq = bdseq
        node.last_death_line, node.last_death_timestamp = rec["line"], rec.get("timestamp")
        for device in node.devices.values():
            device.born = False

    def on_ndata(self, node, rec):
        if not node.born:
            self.fail("birth-first", rec, "NDATA of a node that is not born (no NBIRTH since its start or NDEATH)")
        self.check_seq(node, rec)
        self.data_metrics(node, rec, alias_only=False)

    def on_dbirth(self, node, rec):
        if not node.born:
            self.fail("birth-first", rec, "DBIRTH of a node that is not born")
        self.check_seq(node, rec)
        device = node.device(rec["device"])
        if device.born:
            self.note(rec, f"DBIRTH of {rec['device']!r}, born at line {device.birth_line} with no DDEATH since")
        infos, last, values = self.birth_metrics(node, rec["device"], rec)
        if LAST_ERROR not in {i.name for i in infos.values()}:
            self.fail("dbirth", rec, f"no {LAST_ERROR!r} metric")
        else:
            info = next(i for i in infos.values() if i.name == LAST_ERROR)
            if info.datatype != 12:
                self.fail("dbirth", rec, f"{LAST_ERROR!r} is {dt_name(info.datatype)}, must be String")
        device.born, device.birth_line = True, rec["line"]
        device.metrics, device.last, device.values = infos, last, values
        device.historical = {}

    def on_ddata(self, node, rec):
        if not node.born:
            self.fail("birth-first", rec, "DDATA of a node that is not born")
        self.check_seq(node, rec)
        device = node.device(rec["device"])
        if not device.born:
            self.fail("birth-first", rec, f"DDATA of {rec['device']!r}, which is not born (no DBIRTH since the "
                      "NBIRTH or its DDEATH)")
        self.data_metrics(device, rec, alias_only=True)

    def on_ddeath(self, node, rec):
        if not node.born:
            self.fail("birth-first", rec, "DDEATH of a node that is not born")
        self.check_seq(node, rec)
        device = node.device(rec["device"])
        if not device.born:
            self.fail("birth-first", rec, f"DDEATH of {rec['device']!r}, which is not born")
        if rec["metrics"]:
            self.fail("ddeath", rec, f"DDEATH carries metrics {[m.get('name', m.get('alias')) for m in rec['metrics']]}; "
                      "it has only seq and timestamp")
        device.born = False

    def on_ncmd(self, node, rec):
        pass

    def on_dcmd(self, node, rec):
        pass

    def on_state(self, rec):
        state = rec.get("state")
        if not isinstance(state, dict) or not isinstance(state.get("online"), bool) \
                or not isinstance(state.get("timestamp"), int):
            self.fail("state", rec, f"STATE payload {state!r} is not {{\"online\": bool, \"timestamp\": ms}}")
            return
        self.hosts[rec["host"]] = state["online"]


def describe_key(key):
    device, name = key
    return f"{name!r} of device {device!r}" if device else f"node metric {name!r}"


def resolved(name, alias, datatype, value, is_null, quality, props):
    return {"name": name, "alias": alias, "datatype": datatype, "value": value, "is_null": is_null,
            "quality": quality, "props": props}


# --- Filters shared by wait, count, value, show -----------------------------------------------------

def name_matches(name, suffix):
    """Names may carry the device profile's group ("SP/set_point"): a suffix matches a whole
    name or its last levels."""
    return name is not None and (name == suffix or name.endswith("/" + suffix))


def value_equals(value, text):
    """Whether VALUE (as a host reads it) is what TEXT, from the command line, says."""
    if isinstance(value, bool):
        return text.lower() == ("true" if value else "false")
    if isinstance(value, (int, float)):
        try:
            return abs(float(text) - value) < 1e-9
        except ValueError:
            return False
    return value == text


def metric_predicate(spec):
    """SUFFIX=VALUE, SUFFIX!=VALUE, SUFFIX=null or SUFFIX alone (present in the message)."""
    for op in ("!=", "="):
        if op in spec:
            suffix, text = spec.split(op, 1)
            break
    else:
        suffix, op, text = spec, None, None

    def test(rec):
        for r in rec.get("_resolved", ()):
            if not name_matches(r["name"], suffix):
                continue
            if op is None:
                return True
            if text == "null":
                if r["is_null"] == (op == "="):
                    return True
            elif not r["is_null"] and value_equals(r["value"], text) == (op == "="):
                # A null matches no value comparison, "!=" included: 'Last Error!=' means a
                # non-empty string, not "anything but the empty string".
                return True
        return False
    return test


def add_filters(p):
    p.add_argument("--type", help="message type (NBIRTH, DDATA...), or several joined by commas")
    p.add_argument("--edge")
    p.add_argument("--device")
    p.add_argument("--host", help="STATE host id")
    p.add_argument("--after-line", type=int, default=0, help="only messages after this line")
    p.add_argument("--before-line", type=int, default=None, help="only messages before this line")
    p.add_argument("--metric", action="append", default=[],
                   help="SUFFIX, SUFFIX=VALUE, SUFFIX!=VALUE or SUFFIX=null: a metric (named by suffix; "
                        "data metrics through their birth's alias) present or with that value")
    p.add_argument("--seq-wrap", action="store_true", help="a message whose seq went 255 -> 0")


def filter_of(args):
    types = set(args.type.split(",")) if args.type else None
    predicates = [metric_predicate(s) for s in args.metric]

    def test(rec):
        if rec["line"] <= args.after_line:
            return False
        if args.before_line is not None and rec["line"] >= args.before_line:
            return False
        if types and rec.get("type") not in types:
            return False
        if args.edge and rec.get("edge") != args.edge:
            return False
        if args.device and rec.get("device") != args.device:
            return False
        if args.host and rec.get("host") != args.host:
            return False
        if args.seq_wrap and not rec.get("_wrap"):
            return False
        return all(p(rec) for p in predicates)
    return test


def describe_filter(args):
    parts = [f"{k.replace('_', '-')} {v}" for k, v in vars(args).items()
             if k in ("type", "edge", "device", "host", "after_line") and v]
    parts += [f"metric {m}" for m in args.metric]
    if args.seq_wrap:
        parts.append("seq wrap 255 -> 0")
    return ", ".join(parts)


def replay(path):
    model = Model()
    records = load(path)
    for rec in records:
        model.feed(rec)
    return model, records


# --- Printing -----------------------------------------------------------------------------------

def format_value(value):
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float) and value.is_integer():
        return repr(value)
    return str(value) if not isinstance(value, str) else value


def brief(rec, limit=12):
    """One line for a message, data metrics named from their birth."""
    head = f"line {rec.get('line')} {rec.get('type')} {rec['topic']}"
    if rec.get("type") == "STATE":
        return f"{head} {json.dumps(rec.get('state'))} retain={rec.get('retain')}"
    if rec.get("error"):
        return f"{head} ERROR {rec['error']}"
    head += f" seq={rec.get('seq')} ts={rec.get('timestamp')}"
    shown = []
    for r in rec.get("_resolved", [])[:limit]:
        text = f"{r['name']}#{r['alias']}"
        text += "=null" if r["is_null"] else f"={format_value(r['value'])!r}" if isinstance(r["value"], str) \
            else f"={format_value(r['value'])}"
        props = {k: v for k, v in r["props"].items()}
        if props:
            text += " " + json.dumps(props, ensure_ascii=False, separators=(",", ":"))
        if r["datatype"] is not None:
            text += f" [{dt_name(r['datatype'])}]"
        shown.append(text)
    more = len(rec.get("_resolved", [])) - limit
    if more > 0:
        shown.append(f"... {more} more")
    return head + (": " + "; ".join(shown) if shown else "")


# --- Subcommands -------------------------------------------------------------------------------------

def cmd_record(args):
    import paho.mqtt.client as mqtt
    from paho.mqtt.subscribeoptions import SubscribeOptions

    out = open(args.out, "a", encoding="utf-8")
    line = [sum(1 for _ in open(args.out, encoding="utf-8"))]
    lock = threading.Lock()

    connections = [0]

    def on_connect(client, userdata, flags, rc, properties=None):
        if rc != 0:
            print(f"connect refused: {rc}", flush=True)
            return
        connections[0] += 1
        if connections[0] > 1:
            # Connected again (the broker was restarted): a record of it, before what the broker
            # kept for this session while it was away, so that `check` knows the nodes' connections
            # ended with no NDEATH (the old broker took their wills with it).
            with lock:
                line[0] += 1
                rec = {"line": line[0], "t": now_ms(), "topic": "", "type": "BROKER", "event": "reconnected",
                       "session_present": bool(flags.get("session present"))}
                out.write(json.dumps(rec) + "\n")
                out.flush()
            print(f"connected again (session present: {bool(flags.get('session present'))})", flush=True)
        # retainAsPublished: the retain flag as the publisher set it, so a node publishing
        # retained is seen even while this subscriber is online.
        client.subscribe(f"{NAMESPACE}/#", options=SubscribeOptions(qos=1, retainAsPublished=True))

    def on_subscribe(client, userdata, mid, reason_codes, properties=None):
        print(f"subscribed to {NAMESPACE}/#: {[str(r) for r in reason_codes]}", flush=True)

    def on_message(client, userdata, msg):
        rec = transcribe(msg.topic, msg.payload, msg.qos, msg.retain, now_ms())
        with lock:
            line[0] += 1
            rec = {"line": line[0], **rec}
            # One write per message: a reader sees whole lines or a last line without newline.
            out.write(json.dumps(rec, ensure_ascii=False) + "\n")
            out.flush()

    def on_disconnect(client, userdata, rc, properties=None):
        print(f"disconnected: {rc}", flush=True)

    client = mqtt.Client(client_id=f"sparkplug-check-recorder-{os.getpid()}", protocol=mqtt.MQTTv5)
    client.on_connect, client.on_subscribe = on_connect, on_subscribe
    client.on_message, client.on_disconnect = on_message, on_disconnect
    if args.session:
        # A session the broker keeps (and, with its persistence, across its restart) with what is
        # published while this recorder is away: a broker restarted loses none of the messages.
        from paho.mqtt.packettypes import PacketTypes
        from paho.mqtt.properties import Properties
        connect_properties = Properties(PacketTypes.CONNECT)
        connect_properties.SessionExpiryInterval = int(args.session)
        client.reconnect_delay_set(min_delay=1, max_delay=1)
        client.connect(args.host, args.port, keepalive=30, clean_start=False, properties=connect_properties)
    else:
        client.connect(args.host, args.port, keepalive=30)
    client.loop_start()
    time.sleep(args.duration)
    client.disconnect()
    client.loop_stop()
    return 0


def cmd_wait(args):
    rec_file = Recording(args.log)
    model = Model()
    test = filter_of(args)
    deadline = time.monotonic() + args.timeout
    recent = []
    while True:
        for rec in rec_file.new_records():
            model.feed(rec)
            if (not args.edge or rec.get("edge") == args.edge) and \
                    (not args.device or rec.get("device") == args.device):
                recent = (recent + [rec])[-6:]
            if test(rec):
                print(brief(rec, limit=6))  # "line N ...": the shell takes N from it
                return 0
        if time.monotonic() >= deadline:
            break
        time.sleep(0.05)
    print(f"timeout: {args.timeout:g} s without a message matching: {describe_filter(args)}", file=sys.stderr)
    for node in model.nodes.values():
        if not args.edge or node.edge == args.edge:
            print(f"  node {node.group}/{node.edge}: born={node.born} bdSeq={node.bdseq} last seq={node.seq} "
                  f"({node.seq_messages} seq messages since its NBIRTH, {node.wraps} wraps), counts {node.counts}",
                  file=sys.stderr)
    print("  the last messages of that node/device:" if recent else "  no message of that node/device",
          file=sys.stderr)
    for rec in recent:
        print("    " + brief(rec, limit=6), file=sys.stderr)
    return 1


def cmd_count(args):
    model, records = replay(args.log)
    test = filter_of(args)
    print(sum(1 for rec in records if test(rec)))
    return 0


def cmd_show(args):
    model, records = replay(args.log)
    test = filter_of(args)
    for rec in [r for r in records if test(r)][-args.limit:]:
        print(brief(rec, limit=args.metrics))
    return 0


def find_metric(rec, suffix):
    hits = [r for r in rec.get("_resolved", ()) if name_matches(r["name"], suffix)]
    if len(hits) > 1:
        raise SystemExit(f"{suffix!r} matches {[h['name'] for h in hits]} in line {rec['line']}: name it more fully")
    return hits[0] if hits else None


def pick(resolved_metric, what):
    if what == "value":
        return "null" if resolved_metric["is_null"] else format_value(resolved_metric["value"])
    if what in ("alias", "datatype", "name", "quality"):
        return format_value(resolved_metric[what])
    if what.startswith("prop:"):
        key = what[5:]
        return format_value(resolved_metric["props"][key]) if key in resolved_metric["props"] else "-"
    raise SystemExit(f"unknown --what {what!r}")


def cmd_value(args):
    model, records = replay(args.log)
    if args.line is not None:
        rec = next((r for r in records if r["line"] == args.line), None)
        if rec is None:
            raise SystemExit(f"no line {args.line} in {args.log}")
        if args.what == "seq":
            print(format_value(rec.get("seq")))
            return 0
        if args.what == "text":
            print(brief(rec))
            return 0
        hit = find_metric(rec, args.metric)
        if hit is None:
            raise SystemExit(f"no metric {args.metric!r} in {brief(rec)}")
        print(pick(hit, args.what))
        return 0
    # --latest: the value a host holds now for a device's metric, from its births and data.
    for node in model.nodes.values():
        if args.edge and node.edge != args.edge:
            continue
        owner = node.devices.get(args.device) if args.device else node
        if owner is None:
            continue
        hits = [n for n in owner.values if name_matches(n, args.metric)]
        if len(hits) == 1:
            print(format_value(owner.values[hits[0]]) if owner.values[hits[0]] is not None else "null")
            return 0
    raise SystemExit(f"no current value for {args.metric!r} of {args.edge}/{args.device}")


def cmd_historical(args):
    """Store and forward, for the messages of one node after a line. Prints the figures; the
    exit status says whether they hold: each historical value once (no two with the same device,
    metric and timestamp, and none the births or live data also carried), in its metric's order,
    all of a device's before its first live DDATA after its birth, every one with a timestamp
    between --from-ms and --to-ms when given, and at least --at-least of them."""
    model, records = replay(args.log)
    historical = duplicates = out_of_order = after_live = outside = 0
    live = set()    # (device, name, timestamp) of every birth or live data value
    kept = {}       # (device, name, timestamp) -> how often it came as historical
    last_ts = {}    # (device, name) -> last historical timestamp
    live_since_birth = {}
    first = last = None
    for rec in records:
        if rec["line"] <= args.after_line or rec.get("edge") != args.edge:
            continue
        kind, device = rec.get("type"), rec.get("device")
        if kind == "DBIRTH":
            live_since_birth[device] = False
        if kind not in ("DBIRTH", "DDATA"):
            continue
        any_historical = False
        for m, r in zip(rec["metrics"], rec["_resolved"]):
            key = (device, r["name"], m.get("timestamp"))
            if not m.get("is_historical"):
                live.add(key)
                continue
            any_historical = True
            historical += 1
            kept[key] = kept.get(key, 0) + 1
            ts = m.get("timestamp")
            first = ts if first is None else min(first, ts)
            last = ts if last is None else max(last, ts)
            before = last_ts.get((device, r["name"]))
            if before is not None and ts <= before:
                out_of_order += 1
            last_ts[(device, r["name"])] = ts
            if live_since_birth.get(device):
                after_live += 1
            if (args.from_ms is not None and ts < args.from_ms) or (args.to_ms is not None and ts > args.to_ms):
                outside += 1
        if kind == "DDATA" and not any_historical:
            live_since_birth[device] = True
    duplicates = sum(count - 1 for count in kept.values()) + sum(1 for key in kept if key in live)
    print(f"historical={historical} duplicates={duplicates} out_of_order={out_of_order} after_live={after_live} "
          f"outside_window={outside} first_ms={first} last_ms={last}")
    ok = duplicates == 0 and out_of_order == 0 and after_live == 0 and outside == 0 and historical >= args.at_least
    return 0 if ok else 1


def cmd_series(args):
    """Every value of one device's metric in the recording, in arrival order, one a line:
    LINE TYPE TIMESTAMP VALUE H|L (historical or live; a birth's is live), for a comparison
    with another record of the same values (the gateway's [history])."""
    model, records = replay(args.log)
    for rec in records:
        if rec.get("edge") != args.edge or rec.get("device") != args.device or rec.get("type") not in ("DBIRTH", "DDATA"):
            continue
        for m, r in zip(rec["metrics"], rec["_resolved"]):
            if name_matches(r["name"], args.metric):
                value = "null" if r["is_null"] else format_value(r["value"])
                print(f"{rec['line']} {rec['type']} {m.get('timestamp')} {value} {'H' if m.get('is_historical') else 'L'}")
    return 0


def spec_matches(actual, want):
    """WANT from the command line: '*' present, '-' absent, 'a|b' either, else equal."""
    if want == "*":
        return actual is not None
    if want == "-":
        return actual is None
    if actual is None:
        return False
    return any(value_equals(actual, alt) for alt in want.split("|"))


def cmd_expect_metrics(args):
    """Each SPEC is 'SUFFIX;key=value;...' with key datatype, value, null, alias or a property;
    ';' separates because metric names hold spaces."""
    model, records = replay(args.log)
    rec = next((r for r in records if r["line"] == args.line), None)
    if rec is None:
        raise SystemExit(f"no line {args.line} in {args.log}")
    problems = []
    failed_specs = 0
    for spec in args.specs:
        suffix, *pairs = spec.split(";")
        hit = find_metric(rec, suffix)
        if hit is None:
            problems.append(f"{suffix!r}: no such metric")
            failed_specs += 1
            continue
        before = len(problems)
        for pair in pairs:
            key, want = pair.split("=", 1)
            if key == "value":
                actual = None if hit["is_null"] else hit["value"]
            elif key == "null":
                actual = hit["is_null"]
            elif key in ("datatype", "alias"):
                actual = hit[key]
            else:
                actual = hit["props"].get(key)
            if not spec_matches(actual, want):
                problems.append(f"{hit['name']!r}: {key} is {format_value(actual) if actual is not None else 'absent'}, "
                                f"expected {want or repr('')}")
        failed_specs += len(problems) > before
    if args.any and failed_specs < len(args.specs):
        print(f"ok: line {rec['line']}: {len(args.specs) - failed_specs} of {len(args.specs)} metrics as expected "
              "(one is enough)")
        return 0
    if problems:
        if args.any:
            print(f"none of the {len(args.specs)} metrics as expected (one would have been enough):")
        print(f"in {brief(rec, limit=40)}")
        for p in problems:
            print("  " + p)
        return 1
    print(f"ok: line {rec['line']}: {len(args.specs)} metrics as expected")
    return 0


def cmd_check(args):
    model, records = replay(args.log)
    by_rule = {}
    for rule, line, text in model.failures:
        by_rule.setdefault(rule, []).append(text)
    extra = []
    for edge in args.require_wrap:
        nodes = [n for n in model.nodes.values() if n.edge == edge]
        if not any(n.wraps for n in nodes):
            extra.append(f"[seq-wrap] node {edge!r}: no seq wrap 255 -> 0 observed "
                         f"({sum(n.counts.get(t, 0) for n in nodes for t in SEQ_MESSAGES)} seq messages)")
    print(f"{len(records)} messages recorded")
    for node in model.nodes.values():
        print(f"node {node.group}/{node.edge}: {dict(sorted(node.counts.items()))}; bdSeq of its NBIRTHs "
              f"{node.bdseqs}; seq wraps {node.wraps}; devices {sorted(node.devices)}")
    for host, online in model.hosts.items():
        print(f"host {host}: last STATE online={online}")
    if model.notes:
        # The same remark about many messages is one line: its first message and how many.
        grouped = {}
        for where, text in model.notes:
            grouped.setdefault(text, []).append(where)
        print(f"{len(model.notes)} notes (not failures), {len(grouped)} distinct:")
        for text, wheres in list(grouped.items())[:args.limit]:
            more = f" (and {len(wheres) - 1} more messages)" if len(wheres) > 1 else ""
            print(f"  note: {wheres[0]}: {text}{more}")
        if len(grouped) > args.limit:
            print(f"  ... and {len(grouped) - args.limit} more distinct notes")
    problems = sum(len(v) for v in by_rule.values()) + len(extra)
    for rule, texts in by_rule.items():
        print(f"FAILED rule {rule}: {len(texts)} times")
        for t in texts[:args.limit]:
            print("  " + t)
        if len(texts) > args.limit:
            print(f"  ... and {len(texts) - args.limit} more")
    for t in extra:
        print("FAILED " + t)
    print(f"checked {len(records)} messages, {problems} problems")
    return 1 if problems else 0


# --- Publishing what a host sends ------------------------------------------------------------------------

def publish(args, topic, payload, retain=False):
    import paho.mqtt.client as mqtt
    client = mqtt.Client(client_id=f"sparkplug-check-host-{os.getpid()}", protocol=mqtt.MQTTv311)
    client.connect(args.host, args.port, keepalive=30)
    client.loop_start()
    info = client.publish(topic, payload, qos=1, retain=retain)
    info.wait_for_publish(timeout=15)
    ok = info.is_published()
    client.disconnect()
    client.loop_stop()
    if not ok:
        raise SystemExit(f"publishing to {topic} was not acknowledged within 15 s")


def cmd_publish_ncmd(args):
    metrics = [{"name": REBIRTH, "datatype": 11, "value": True, "timestamp": now_ms()}] if args.rebirth else []
    for spec in args.metric:
        name, datatype, value = spec.split(":", 2)
        metrics.append({"name": name, "datatype": int(datatype), "value": value, "timestamp": now_ms()})
    payload = build_payload(timestamp=now_ms(), metrics=metrics)
    topic = f"{NAMESPACE}/{args.group}/NCMD/{args.edge}"
    publish(args, topic, payload.SerializeToString())
    print(f"published {topic}: {[m['name'] for m in metrics]}")
    return 0


def cmd_publish_dcmd(args):
    """Names the metric as the device's latest DBIRTH does, so the test need not know whether
    the gateway puts the profile's group in front of the parameter's name."""
    model, records = replay(args.log)
    birth = None
    for rec in records:
        if rec.get("type") == "DBIRTH" and rec.get("edge") == args.edge and rec.get("device") == args.device:
            birth = rec
    if birth is None:
        raise SystemExit(f"no DBIRTH of {args.edge}/{args.device} in {args.log}")
    hit = find_metric(birth, args.metric)
    if hit is None:
        raise SystemExit(f"no metric {args.metric!r} in {brief(birth)}")
    datatype = args.datatype if args.datatype is not None else hit["datatype"]
    metric = {"timestamp": now_ms(), "value": args.value, "value_type": datatype}
    if not args.no_datatype:
        metric["datatype"] = datatype
    if args.by == "name":
        metric["name"] = hit["name"]
    else:
        metric["alias"] = hit["alias"]
    payload = build_payload(timestamp=now_ms(), metrics=[metric])
    topic = f"{NAMESPACE}/{birth['group']}/DCMD/{args.edge}/{args.device}"
    publish(args, topic, payload.SerializeToString(), retain=args.retain)
    print(f"published {topic}{' (retained)' if args.retain else ''}: {hit['name']!r} (alias {hit['alias']}) by "
          f"{args.by} = {args.value!r} as {dt_name(datatype)}")
    return 0


def cmd_publish_state(args):
    online = args.online.lower() == "true"
    timestamp = now_ms() - args.age_ms
    body = json.dumps({"online": online, "timestamp": timestamp})
    topic = f"{NAMESPACE}/STATE/{args.host_id}"
    publish(args, topic, body.encode(), retain=True)
    print(f"published {topic} (retained): {body}")
    return 0


def cmd_flap_state(args):
    """COUNT STATEs, offline and online in turn (online last), retained as a host publishes
    them, EVERY seconds apart, on one connection; each acknowledged before the next."""
    import paho.mqtt.client as mqtt
    client = mqtt.Client(client_id=f"sparkplug-check-flapper-{os.getpid()}", protocol=mqtt.MQTTv311)
    client.connect(args.host, args.port, keepalive=30)
    client.loop_start()
    topic = f"{NAMESPACE}/STATE/{args.host_id}"
    try:
        for i in range(args.count):
            online = (args.count - 1 - i) % 2 == 0
            body = json.dumps({"online": online, "timestamp": now_ms()})
            info = client.publish(topic, body.encode(), qos=1, retain=True)
            info.wait_for_publish(timeout=15)
            if not info.is_published():
                raise SystemExit(f"STATE {i + 1} of {args.count} was not acknowledged within 15 s")
            time.sleep(args.every)
    finally:
        client.disconnect()
        client.loop_stop()
    print(f"published {args.count} STATEs on {topic}, {args.every * 1000:g} ms apart, the last online")
    return 0


# --- Self-test -------------------------------------------------------------------------------------------
# The checker is only worth something if it notices broken messages: a healthy synthetic node
# must pass, and each injected fault must be reported under its rule.

class FakeNode:
    """Builds the messages of a well-behaved node, through the protobuf module."""

    def __init__(self, group="g", edge="e"):
        self.group, self.edge = group, edge
        self.seq = 0
        self.records = []
        self.datatypes = {}
        self.t = now_ms()

    def emit(self, kind, device=None, seq=True, metrics=(), retain=False, qos=0, payload_seq=None):
        topic = f"{NAMESPACE}/{self.group}/{kind}/{self.edge}" + (f"/{device}" if device else "")
        if kind == "NBIRTH":
            self.seq = 0
            s = 0
        elif seq:
            self.seq = (self.seq + 1) % 256
            s = self.seq
        else:
            s = None
        if payload_seq is not None:
            s = payload_seq
        self.t += 1
        for m in metrics:
            # Data names metrics by alias alone: the value's field follows the birth's datatype.
            if "alias" in m and "datatype" in m:
                self.datatypes[m["alias"]] = m["datatype"]
            elif "alias" in m:
                m.setdefault("value_type", self.datatypes.get(m["alias"]))
        payload = build_payload(seq=s, timestamp=self.t, metrics=metrics).SerializeToString()
        rec = transcribe(topic, payload, qos, retain, self.t)
        rec["line"] = len(self.records) + 1
        self.records.append(rec)
        return rec

    def nbirth(self, bdseq, **kw):
        return self.emit("NBIRTH", metrics=[
            {"name": BDSEQ, "alias": 1, "datatype": 8, "value": bdseq},
            {"name": REBIRTH, "alias": 2, "datatype": 11, "value": False},
            {"name": "Lines/l/Requests", "alias": 3, "datatype": 8, "value": 5},
            {"name": "Lines/l/Answered", "alias": 4, "datatype": 8, "value": 5},
            {"name": "Lines/l/Timeouts", "alias": 5, "datatype": 8, "value": 0},
            {"name": "Lines/l/Open", "alias": 6, "datatype": 11, "value": True},
        ], **kw)

    def dbirth(self, device, base, temp=25.0, **kw):
        ts = self.t
        return self.emit("DBIRTH", device, metrics=[
            {"name": "variables/temp", "alias": base, "datatype": 10, "value": temp, "timestamp": ts,
             "props": [("engUnit", 12, "°C"), ("readOnly", 11, True), ("writable", 11, False),
                       ("decimals", 3, 1), ("Quality", 3, 192)]},
            {"name": "offset", "alias": base + 1, "datatype": 2, "value": -5, "timestamp": ts,
             "props": [("Quality", 3, 192), ("writable", 11, True), ("readOnly", 11, False)]},
            {"name": "mode", "alias": base + 2, "datatype": 12, "value": "auto", "timestamp": ts,
             "props": [("Quality", 3, 192)]},
            {"name": LAST_ERROR, "alias": base + 3, "datatype": 12, "value": "", "timestamp": ts},
        ], **kw)

    def ddata(self, device, metrics, **kw):
        for m in metrics:
            m.setdefault("timestamp", self.t)
        return self.emit("DDATA", device, metrics=metrics, **kw)

    def ndeath(self, bdseq, **kw):
        return self.emit("NDEATH", seq=False, metrics=[{"name": BDSEQ, "datatype": 8, "value": bdseq}],
                         qos=1, **kw)


def healthy_story():
    n = FakeNode()
    n.nbirth(0)
    n.dbirth("d1", 10)
    n.dbirth("d2", 20)
    for i in range(300):  # enough for a wrap
        n.ddata("d1", [{"alias": 10, "value": 25.0 + 0.1 * (i + 1)}])
    n.ddata("d1", [{"alias": 11, "value": -7}])
    n.ddata("d1", [{"alias": 10, "is_null": True, "props": [("Quality", 3, 500)]}])
    n.ddata("d1", [{"alias": 10, "value": 30.0, "props": [("Quality", 3, 192)]}])
    n.emit("DDEATH", "d2")
    n.dbirth("d2", 20, temp=26.0)
    n.nbirth(0)             # rebirth: same bdSeq, same aliases
    n.dbirth("d1", 10)
    n.dbirth("d2", 20)
    n.ndeath(0)
    n.nbirth(1)             # the same process, next connection
    n.dbirth("d1", 10)
    # Store and forward: the outage's values after the births, historical, in their order; one
    # equal to the birth's is no repetition (a host does not take it for the current value).
    n.ddata("d1", [{"alias": 10, "value": 25.0, "is_historical": True, "timestamp": n.t - 4000}])
    n.ddata("d1", [{"alias": 10, "value": 24.0, "is_historical": True, "timestamp": n.t - 3000},
                   {"alias": 11, "value": -6, "is_historical": True, "timestamp": n.t - 3000}])
    n.ddata("d1", [{"alias": 10, "value": 24.5}])
    n.ndeath(1)
    n.nbirth(0)             # a new process
    n.dbirth("d1", 30)      # may choose other aliases
    return n


def broken_stories():
    """(rule, description, node) for each fault the checker must find."""
    stories = []

    def story(rule, what):
        def deco(f):
            n = FakeNode()
            n.nbirth(0)
            n.dbirth("d1", 10)
            f(n)
            stories.append((rule, what, n))
            return f
        return deco

    @story("data", "DDATA metric named, not by alias alone")
    def _(n):
        n.ddata("d1", [{"alias": 10, "name": "variables/temp", "value": 26.0}])

    @story("data", "DDATA alias of another device")
    def _(n):
        n.dbirth("d2", 20)
        n.ddata("d1", [{"alias": 20, "value": 26.0}])

    @story("data", "DDATA repeats an unchanged value")
    def _(n):
        n.ddata("d1", [{"alias": 10, "value": 25.0}])

    @story("data", "historical values out of their order")
    def _(n):
        n.ddata("d1", [{"alias": 10, "value": 24.0, "is_historical": True, "timestamp": n.t - 2000}])
        n.ddata("d1", [{"alias": 10, "value": 24.5, "is_historical": True, "timestamp": n.t - 3000}])

    @story("data", "a stale value sent with its old number")
    def _(n):
        n.ddata("d1", [{"alias": 10, "value": 26.0, "props": [("Quality", 3, 500)]}])

    @story("data", "is_null with a value")
    def _(n):
        n.ddata("d1", [{"alias": 10, "is_null": True, "value": 26.0, "props": [("Quality", 3, 500)]}])

    @story("data", "null without Quality")
    def _(n):
        n.ddata("d1", [{"alias": 10, "is_null": True}])

    @story("data", "Int16 not sign-extended to 32 bits")
    def _(n):
        n.ddata("d1", [{"alias": 11, "raw_field": "int_value", "raw_value": 0xFFFB}])

    @story("data", "Double sent as float_value")
    def _(n):
        n.ddata("d1", [{"alias": 10, "raw_field": "float_value", "raw_value": 26.5}])

    @story("seq", "seq skips one")
    def _(n):
        n.seq += 1
        n.ddata("d1", [{"alias": 10, "value": 26.0}])

    @story("seq", "rebirth NBIRTH with seq 1")
    def _(n):
        n.nbirth(0, payload_seq=1)

    @story("bdseq", "NDEATH bdSeq differs from the NBIRTH's")
    def _(n):
        n.ndeath(1)

    @story("bdseq", "rebirth changes bdSeq")
    def _(n):
        n.nbirth(1)

    @story("bdseq", "reconnection skips a bdSeq")
    def _(n):
        n.ndeath(0)
        n.nbirth(2)

    @story("bdseq", "an NBIRTH with the bdSeq of the NDEATH just sent (a dead session born again)")
    def _(n):
        n.ndeath(0)
        n.nbirth(1)
        n.dbirth("d1", 10)
        n.ndeath(1)
        n.nbirth(1)  # 1 again, not 2 (0 would read as a new process of the node)

    @story("bdseq", "one connection's NDEATH delivered twice (its own, then the broker's will)")
    def _(n):
        n.ndeath(0)
        n.ndeath(0)

    @story("alias-stable", "alias changes across a rebirth")
    def _(n):
        n.nbirth(0)
        n.dbirth("d1", 40)

    @story("alias-unique", "two devices share aliases")
    def _(n):
        n.dbirth("d2", 10)

    @story("birth-first", "DDATA after DDEATH")
    def _(n):
        n.emit("DDEATH", "d1")
        n.ddata("d1", [{"alias": 10, "value": 26.0}])

    @story("birth-first", "DDATA after NDEATH")
    def _(n):
        n.ndeath(0)
        n.ddata("d1", [{"alias": 10, "value": 26.0}])

    @story("birth-first", "DDATA after a rebirth's NBIRTH before the DBIRTH")
    def _(n):
        n.nbirth(0)
        n.ddata("d1", [{"alias": 10, "value": 26.0}])

    @story("ddeath", "DDEATH with metrics")
    def _(n):
        n.emit("DDEATH", "d1", metrics=[{"name": "x", "datatype": 11, "value": True}])

    @story("ndeath", "NDEATH with seq")
    def _(n):
        n.emit("NDEATH", seq=True, metrics=[{"name": BDSEQ, "datatype": 8, "value": 0}])

    @story("retained", "retained DDATA")
    def _(n):
        n.ddata("d1", [{"alias": 10, "value": 26.0}], retain=True)

    @story("timestamp", "timestamp in seconds")
    def _(n):
        n.ddata("d1", [{"alias": 10, "value": 26.0, "timestamp": n.t // 1000}])

    @story("metric", "DBIRTH metric without a timestamp")
    def _(n):
        n.emit("DBIRTH", "d3", metrics=[{"name": "a", "alias": 50, "datatype": 10, "value": 1.0},
                                        {"name": LAST_ERROR, "alias": 51, "datatype": 12, "value": "",
                                         "timestamp": n.t}])

    @story("metric", "a property of the wrong type")
    def _(n):
        n.emit("DBIRTH", "d3", metrics=[
            {"name": "a", "alias": 50, "datatype": 10, "value": 1.0, "timestamp": n.t,
             "props": [("Quality", 10, 192.0)]},
            {"name": LAST_ERROR, "alias": 51, "datatype": 12, "value": "", "timestamp": n.t}])

    @story("dbirth", "DBIRTH without Last Error")
    def _(n):
        n.emit("DBIRTH", "d3", metrics=[{"name": "a", "alias": 50, "datatype": 10, "value": 1.0,
                                         "timestamp": n.t}])

    @story("decode", "a payload that is not protobuf")
    def _(n):
        rec = transcribe(f"{NAMESPACE}/g/DDATA/e/d1", b"\xff\xff\xff", 0, False, n.t)
        rec["line"] = len(n.records) + 1
        n.records.append(rec)

    return stories


def cmd_selftest(args):
    failures = []

    # 1. Round trip: every value kind and property through encode -> wire -> transcribe.
    t = now_ms()
    p = build_payload(seq=7, timestamp=t, metrics=[
        {"name": "i16", "alias": 1, "datatype": 2, "value": -5, "timestamp": t},
        {"name": "u16", "alias": 2, "datatype": 6, "value": 65535},
        {"name": "u64", "alias": 3, "datatype": 8, "value": 2 ** 64 - 1},
        {"name": "d", "alias": 4, "datatype": 10, "value": 21.5,
         "props": [("engUnit", 12, "°C"), ("engLow", 10, -1999.0), ("decimals", 3, 1),
                   ("readOnly", 11, True), ("Quality", 3, 192)]},
        {"name": "b", "alias": 5, "datatype": 11, "value": False},
        {"name": "s", "alias": 6, "datatype": 12, "value": "manual"},
        {"name": "n", "alias": 7, "datatype": 10, "is_null": True, "props": [("Quality", 3, 500)]},
    ])
    wire = p.SerializeToString()
    rec = transcribe(f"{NAMESPACE}/g/DDATA/e/d", wire, 0, False, t)
    rec = json.loads(json.dumps(rec))  # through the recording's JSON, as the tools read it
    ms = {m["name"]: m for m in rec["metrics"]}
    expectations = [
        (rec["seq"], 7), (rec["timestamp"], t), (rec["device"], "d"), (rec["type"], "DDATA"),
        (ms["i16"]["field"], "int_value"), (ms["i16"]["value"], 2 ** 32 - 5), (ms["i16"]["timestamp"], t),
        (interpret("int_value", ms["i16"]["value"], 2, []), -5),
        (ms["u16"]["value"], 65535), (ms["u64"]["value"], 2 ** 64 - 1),
        (ms["d"]["value"], 21.5), (ms["b"]["value"], False), ("value" in ms["b"], True),
        (ms["s"]["value"], "manual"), (ms["n"].get("is_null"), True), ("field" in ms["n"], False),
        ("is_null" in ms["d"], False),
        (read_properties(ms["d"], [], []), {"engUnit": "°C", "engLow": -1999.0, "decimals": 1,
                                            "readOnly": True, "Quality": 192}),
    ]
    for i, (got, want) in enumerate(expectations):
        if got != want:
            failures.append(f"round trip #{i}: got {got!r}, expected {want!r}")
    # Decoding the wire bytes with the generated class directly agrees with the record.
    q = pb2().Payload.FromString(wire)
    if q.metrics[0].int_value != 2 ** 32 - 5 or q.metrics[6].HasField("double_value"):
        failures.append("the generated class reads the payload differently")

    # 2. A healthy node passes, and its seq wrapped.
    model = Model()
    n = healthy_story()
    for rec in n.records:
        model.feed(json.loads(json.dumps(rec)))
    for rule, line, text in model.failures:
        failures.append(f"healthy node flagged: {text}")
    node = model.nodes[("g", "e")]
    if node.wraps < 1:
        failures.append(f"healthy node: no seq wrap seen after {len(n.records)} messages")

    # 3. Each broken story is caught by its rule.
    for rule, what, n in broken_stories():
        model = Model()
        for rec in n.records:
            model.feed(json.loads(json.dumps(rec)))
        rules = {r for r, _, _ in model.failures}
        if rule not in rules:
            failures.append(f"not caught: {what} (expected rule {rule}, got {sorted(rules) or 'none'})")
        elif args.verbose:
            print(f"caught: {what}: " + next(t for r, _, t in model.failures if r == rule))

    for f in failures:
        print("FAIL " + f)
    print(f"selftest: {'ok' if not failures else 'FAILED'} ({len(broken_stories())} broken stories, "
          f"{len(failures)} failures)")
    return 1 if failures else 0


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--pb", help="directory holding sparkplug_b_pb2.py (default: $SPARKPLUG_PB_DIR)")
    sub = ap.add_subparsers(dest="command", required=True)

    def broker(p):
        p.add_argument("--host", default="127.0.0.1")
        p.add_argument("--port", type=int, required=True)

    p = sub.add_parser("record", help="record every spBv1.0/# message")
    broker(p)
    p.add_argument("--out", required=True)
    p.add_argument("--duration", type=float, default=300, help="stop after this many seconds")
    p.add_argument("--session", type=int, default=0,
                   help="keep a session this many seconds (MQTT 5 session expiry): with a broker that persists "
                        "sessions and queues QoS 0 messages, nothing is lost across its restart")
    p.set_defaults(func=cmd_record)

    p = sub.add_parser("wait", help="wait for a message matching the filter")
    p.add_argument("log")
    add_filters(p)
    p.add_argument("--timeout", type=float, default=30)
    p.set_defaults(func=cmd_wait)

    p = sub.add_parser("count", help="count messages matching the filter")
    p.add_argument("log")
    add_filters(p)
    p.set_defaults(func=cmd_count)

    p = sub.add_parser("show", help="print messages matching the filter")
    p.add_argument("log")
    add_filters(p)
    p.add_argument("--limit", type=int, default=1000, help="the last N matching messages")
    p.add_argument("--metrics", type=int, default=40, help="metrics shown per message")
    p.set_defaults(func=cmd_show)

    p = sub.add_parser("historical", help="figures of store and forward: historical values, duplicates, order")
    p.add_argument("log")
    p.add_argument("--edge", required=True)
    p.add_argument("--after-line", type=int, default=0)
    p.add_argument("--from-ms", type=int, help="every historical value is of this time or later")
    p.add_argument("--to-ms", type=int, help="every historical value is of this time or earlier")
    p.add_argument("--at-least", type=int, default=1, help="historical values expected at least")
    p.set_defaults(func=cmd_historical)

    p = sub.add_parser("series", help="every value of one device's metric: line, type, timestamp, value, H|L")
    p.add_argument("log")
    p.add_argument("--edge", required=True)
    p.add_argument("--device", required=True)
    p.add_argument("--metric", required=True, help="metric name suffix")
    p.set_defaults(func=cmd_series)

    p = sub.add_parser("value", help="print one field of a message, or a device's current value")
    p.add_argument("log")
    p.add_argument("--line", type=int)
    p.add_argument("--latest", action="store_true", help="the value a host holds now (with --edge, --device)")
    p.add_argument("--edge")
    p.add_argument("--device")
    p.add_argument("--metric", help="metric name suffix")
    p.add_argument("--what", default="value",
                   help="value, alias, datatype, name, quality, prop:KEY; seq or text of the message")
    p.set_defaults(func=cmd_value)

    p = sub.add_parser("expect-metrics", help="assert the metrics of one message")
    p.add_argument("log")
    p.add_argument("--line", type=int, required=True)
    p.add_argument("--any", action="store_true", help="pass when at least one SPEC holds entirely")
    p.add_argument("specs", nargs="+", help="SUFFIX;key=value;... (key: datatype, value, null, alias or a "
                   "property; value '*' present, '-' absent, 'a|b' either)")
    p.set_defaults(func=cmd_expect_metrics)

    p = sub.add_parser("check", help="check the whole recording against the Sparkplug rules")
    p.add_argument("log")
    p.add_argument("--require-wrap", action="append", default=[], metavar="EDGE",
                   help="fail unless this node's seq wrapped 255 -> 0")
    p.add_argument("--limit", type=int, default=15, help="failures printed per rule")
    p.set_defaults(func=cmd_check)

    p = sub.add_parser("publish-ncmd", help="publish an NCMD")
    broker(p)
    p.add_argument("--group", required=True)
    p.add_argument("--edge", required=True)
    p.add_argument("--rebirth", action="store_true", help="Node Control/Rebirth = true")
    p.add_argument("--metric", action="append", default=[], help="NAME:DATATYPE:VALUE")
    p.set_defaults(func=cmd_publish_ncmd)

    p = sub.add_parser("publish-dcmd", help="publish a DCMD for a metric of the device's last DBIRTH")
    broker(p)
    p.add_argument("--log", required=True, help="the recording (for the metric's name, alias, datatype)")
    p.add_argument("--edge", required=True)
    p.add_argument("--device", required=True)
    p.add_argument("--metric", required=True, help="name suffix")
    p.add_argument("--value", required=True)
    p.add_argument("--by", choices=("name", "alias"), default="name")
    p.add_argument("--datatype", type=int, help="send as this datatype instead of the birth's")
    p.add_argument("--no-datatype", action="store_true", help="leave the datatype out")
    p.add_argument("--retain", action="store_true", help="publish it with the retain flag")
    p.set_defaults(func=cmd_publish_dcmd)

    p = sub.add_parser("publish-state", help="publish the primary host's STATE (retained)")
    broker(p)
    p.add_argument("--host-id", required=True)
    p.add_argument("--online", required=True, choices=("true", "false"))
    p.add_argument("--age-ms", type=int, default=0, help="a timestamp this many ms before now (a late STATE)")
    p.set_defaults(func=cmd_publish_state)

    p = sub.add_parser("flap-state", help="publish the host's STATE offline and online in turn, the last online")
    broker(p)
    p.add_argument("--host-id", required=True)
    p.add_argument("--count", type=int, default=100)
    p.add_argument("--every", type=float, default=0.02, help="seconds between two STATEs")
    p.set_defaults(func=cmd_flap_state)

    p = sub.add_parser("selftest", help="prove the decoder and the rules on synthetic messages")
    p.add_argument("-v", "--verbose", action="store_true")
    p.set_defaults(func=cmd_selftest)

    args = ap.parse_args()
    if args.pb:
        pb2(args.pb)
    return args.func(args)


if __name__ == "__main__":
    sys.exit(main())
