"""An independent MQTT client (paho) reads the gateway's Home Assistant discovery documents and
checks each as Home Assistant would take it.

Schema: each document is validated with voluptuous (the validation library Home Assistant's
MQTT integration uses) against the keys of its platform as Home Assistant's MQTT integration
documentation lists them (sensor, binary_sensor, number, select, climate; the shared entity
options, the device block and availability): a required key missing, a key no platform takes,
a value of the wrong type or outside the documented choices is a problem. Written from those
documentation pages, not copied from Home Assistant's code.

Templates: every template (value_template and the climate's *_template) is rendered with Jinja2,
Home Assistant's template engine, with `value` (and `value_json`) and Home Assistant's
`is_number` filter and test, against every status word the gateway puts on a value topic when
it has no value and against a real value: a word must render to None (Home Assistant's
"unknown": a number's payload_reset, a sensor's and a climate's PAYLOAD_NONE), never to text a
number, a select or a thermostat rejects; a value must render to what the platform takes.

Limits: a number's min/max and a thermostat's min_temp/max_temp are the limits the value's
/meta document gives (the device's), and absent where it gives none.

usage: ha_discovery_check.py PORT DISCOVERY_PREFIX STATE_PREFIX COMPONENT... [--expect=OBJECT_ID=KEY:JSON]...
(KEY:absent and KEY:present ask only whether the document has the key.)
Exits 0 when a document of each COMPONENT came and every document passed; prints what failed
and the counts.
"""
import json
import math
import re
import sys
import threading
import time

import jinja2
import paho.mqtt.client as mqtt
import voluptuous as vol

# What a value topic holds when there is no value (client/device_status.hpp), and a special
# state a device reports in place of a measurement.
STATUS_WORDS = ["error", "stale", "no-reply", "line-down", "wrong-device", "waiting", "under-range"]
NONE = "None"  # Home Assistant's PAYLOAD_NONE and a number's default payload_reset

URL = vol.Match(r"^(https?|homeassistant)://")
TEMPLATE = str
TOPIC = vol.All(str, vol.Length(min=1))

AVAILABILITY = vol.Schema({
    vol.Required("topic"): TOPIC,
    vol.Optional("payload_available"): str,
    vol.Optional("payload_not_available"): str,
    vol.Optional("value_template"): TEMPLATE,
})

DEVICE = vol.All(vol.Schema({
    vol.Optional("identifiers"): vol.All([str], vol.Length(min=1)),
    vol.Optional("connections"): [[str]],
    vol.Optional("configuration_url"): URL,
    vol.Optional("hw_version"): str,
    vol.Optional("manufacturer"): str,
    vol.Optional("model"): str,
    vol.Optional("model_id"): str,
    vol.Optional("name"): str,
    vol.Optional("serial_number"): str,
    vol.Optional("suggested_area"): str,
    vol.Optional("sw_version"): str,
    vol.Optional("via_device"): str,
}), vol.Any(vol.Schema({vol.Required("identifiers"): list}, extra=vol.ALLOW_EXTRA),
            vol.Schema({vol.Required("connections"): list}, extra=vol.ALLOW_EXTRA)))

# The options every MQTT entity takes.
ENTITY = {
    vol.Optional("availability"): [AVAILABILITY],
    vol.Optional("availability_mode"): vol.In(["all", "any", "latest"]),
    vol.Optional("availability_topic"): TOPIC,
    vol.Optional("availability_template"): TEMPLATE,
    vol.Optional("payload_available"): str,
    vol.Optional("payload_not_available"): str,
    vol.Optional("device"): DEVICE,
    vol.Optional("enabled_by_default"): bool,
    vol.Optional("encoding"): str,
    vol.Optional("entity_category"): vol.In(["config", "diagnostic"]),
    vol.Optional("entity_picture"): str,
    vol.Optional("icon"): str,
    vol.Optional("json_attributes_topic"): TOPIC,
    vol.Optional("json_attributes_template"): TEMPLATE,
    vol.Optional("name"): vol.Any(str, None),
    vol.Optional("object_id"): str,
    vol.Optional("default_entity_id"): str,
    vol.Optional("unique_id"): str,
    vol.Optional("qos"): vol.In([0, 1, 2]),
    vol.Optional("origin"): dict,
}
def NUMBER(value):
    """A JSON number (not true or false, which Python counts as numbers)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise vol.Invalid(f"expected a number, got {value!r}")
    return value


STATE_CLASSES = ["measurement", "measurement_angle", "total", "total_increasing"]
BINARY_CLASSES = ["battery", "battery_charging", "carbon_monoxide", "cold", "connectivity", "door", "garage_door", "gas",
                  "heat", "light", "lock", "moisture", "motion", "moving", "occupancy", "opening", "plug", "power",
                  "presence", "problem", "running", "safety", "smoke", "sound", "tamper", "update", "vibration",
                  "window"]
HVAC_MODES = ["auto", "off", "cool", "heat", "dry", "fan_only", "heat_cool"]
HVAC_ACTIONS = ["off", "heating", "cooling", "drying", "idle", "fan", "preheating", "defrosting"]


def platform(keys):
    return vol.Schema({**ENTITY, **keys})


PLATFORMS = {
    "sensor": platform({
        vol.Required("state_topic"): TOPIC,
        vol.Optional("device_class"): str,
        vol.Optional("expire_after"): int,
        vol.Optional("force_update"): bool,
        vol.Optional("last_reset_value_template"): TEMPLATE,
        vol.Optional("options"): [str],
        vol.Optional("state_class"): vol.In(STATE_CLASSES),
        vol.Optional("suggested_display_precision"): vol.All(int, vol.Range(min=0)),
        vol.Optional("unit_of_measurement"): str,
        vol.Optional("value_template"): TEMPLATE,
    }),
    "binary_sensor": platform({
        vol.Required("state_topic"): TOPIC,
        vol.Optional("device_class"): vol.In(BINARY_CLASSES),
        vol.Optional("expire_after"): int,
        vol.Optional("force_update"): bool,
        vol.Optional("off_delay"): int,
        vol.Optional("payload_off"): str,
        vol.Optional("payload_on"): str,
        vol.Optional("value_template"): TEMPLATE,
    }),
    "number": platform({
        vol.Required("command_topic"): TOPIC,
        vol.Optional("command_template"): TEMPLATE,
        vol.Optional("device_class"): str,
        vol.Optional("min"): NUMBER,
        vol.Optional("max"): NUMBER,
        vol.Optional("mode"): vol.In(["auto", "box", "slider"]),
        vol.Optional("optimistic"): bool,
        vol.Optional("payload_reset"): str,
        vol.Optional("retain"): bool,
        vol.Optional("state_topic"): TOPIC,
        vol.Optional("step"): vol.All(NUMBER, vol.Range(min=1e-3)),
        vol.Optional("unit_of_measurement"): str,
        vol.Optional("value_template"): TEMPLATE,
    }),
    "select": platform({
        vol.Required("command_topic"): TOPIC,
        vol.Required("options"): vol.All([str], vol.Length(min=1)),
        vol.Optional("command_template"): TEMPLATE,
        vol.Optional("optimistic"): bool,
        vol.Optional("retain"): bool,
        vol.Optional("state_topic"): TOPIC,
        vol.Optional("value_template"): TEMPLATE,
    }),
    "climate": platform({
        vol.Optional("action_template"): TEMPLATE,
        vol.Optional("action_topic"): TOPIC,
        vol.Optional("current_humidity_template"): TEMPLATE,
        vol.Optional("current_humidity_topic"): TOPIC,
        vol.Optional("current_temperature_template"): TEMPLATE,
        vol.Optional("current_temperature_topic"): TOPIC,
        vol.Optional("initial"): NUMBER,
        vol.Optional("max_temp"): NUMBER,
        vol.Optional("min_temp"): NUMBER,
        vol.Optional("mode_command_template"): TEMPLATE,
        vol.Optional("mode_command_topic"): TOPIC,
        vol.Optional("mode_state_template"): TEMPLATE,
        vol.Optional("mode_state_topic"): TOPIC,
        vol.Optional("modes"): [vol.In(HVAC_MODES)],
        vol.Optional("optimistic"): bool,
        vol.Optional("payload_off"): str,
        vol.Optional("payload_on"): str,
        vol.Optional("power_command_template"): TEMPLATE,
        vol.Optional("power_command_topic"): TOPIC,
        vol.Optional("precision"): vol.In([0.1, 0.5, 1.0]),
        vol.Optional("preset_mode_command_template"): TEMPLATE,
        vol.Optional("preset_mode_command_topic"): TOPIC,
        vol.Optional("preset_mode_state_topic"): TOPIC,
        vol.Optional("preset_mode_value_template"): TEMPLATE,
        vol.Optional("preset_modes"): [vol.All(str, vol.NotIn(["none"]))],
        vol.Optional("retain"): bool,
        vol.Optional("temperature_command_template"): TEMPLATE,
        vol.Optional("temperature_command_topic"): TOPIC,
        vol.Optional("temperature_state_template"): TEMPLATE,
        vol.Optional("temperature_state_topic"): TOPIC,
        vol.Optional("temperature_unit"): vol.In(["C", "F"]),
        vol.Optional("temp_step"): NUMBER,
        vol.Optional("value_template"): TEMPLATE,
    }),
}
OBJECT_ID = re.compile(r"^[A-Za-z0-9_-]+$")


# --- Home Assistant's template environment, as far as the gateway's templates use it ----------

def is_number(value):
    """Home Assistant's is_number: a value float() takes that is finite."""
    try:
        number = float(value)
    except (TypeError, ValueError):
        return False
    return math.isfinite(number)


def ha_float(value, default=None):
    """Home Assistant's float filter: raises without a default where float() does not take it."""
    try:
        return float(value)
    except (TypeError, ValueError):
        if default is None:
            raise ValueError(f"float got invalid input {value!r} and no default was specified")
        return default


ENVIRONMENT = jinja2.Environment(undefined=jinja2.StrictUndefined)
ENVIRONMENT.filters["is_number"] = is_number
ENVIRONMENT.tests["is_number"] = is_number
ENVIRONMENT.filters["float"] = ha_float


def render(template, value):
    variables = {"value": value}
    try:
        variables["value_json"] = json.loads(value)
    except ValueError:
        pass
    return str(ENVIRONMENT.from_string(template).render(**variables)).strip()


def numeric(text):
    try:
        float(text)
        return True
    except ValueError:
        return False


# --- per document ------------------------------------------------------------------------------

def component_of(topic):
    return topic.split("/")[-3]


def check_schema(topic, document):
    component = component_of(topic)
    if component not in PLATFORMS:
        return [f"{topic}: a component this gateway should not publish: {component}"]
    try:
        PLATFORMS[component](document)
    except vol.MultipleInvalid as error:
        return [f"{topic}: {e}" for e in error.errors]
    return []


def check_promises(topic, document, state_prefix, gateway_id):
    """What the gateway promises besides the schema: ids, availability, the device tree."""
    problems = []
    component, object_id = component_of(topic), topic.split("/")[-2]
    if not OBJECT_ID.match(object_id) or document.get("unique_id") != object_id:
        problems.append(f"{topic}: object id {object_id!r} is not the unique_id or not [A-Za-z0-9_-]")
    device = document.get("device", {})
    if "model" not in device or "name" not in device:
        problems.append(f"{topic}: the device block needs a name and a model")
    if document.get("state_topic") == state_prefix + "/status":  # the gateway's own entity
        if device.get("identifiers") != [gateway_id] or "sw_version" not in device:
            problems.append(f"{topic}: the gateway's device is {gateway_id} with loopwire's sw_version")
        return problems
    if device.get("via_device") != gateway_id:
        problems.append(f"{topic}: via_device should be the gateway's device {gateway_id}, is {device.get('via_device')!r}")
    own_state = "temperature_state_topic" if component == "climate" else "state_topic"
    state_topic = document.get(own_state, "")
    if not state_topic.startswith(state_prefix + "/"):
        problems.append(f"{topic}: {own_state} outside {state_prefix}")
    device_availability = "/".join(state_topic.split("/")[:-1]) + "/availability"
    topics = [entry.get("topic") for entry in document.get("availability", [])]
    if topics != [state_prefix + "/status", device_availability] or document.get("availability_mode") != "all":
        problems.append(f"{topic}: availability should be the gateway's status and the device's availability, mode all: {topics}")
    for command in ("command_topic", "temperature_command_topic"):
        if command in document and document[command] != document.get(own_state) + "/set":
            problems.append(f"{topic}: {command} is not the state topic's /set")
    if document.get("device_class") == "temperature" and document.get("unit_of_measurement") not in ("°C", "°F", "K"):
        problems.append(f"{topic}: a temperature in {document.get('unit_of_measurement')!r}")
    if document.get("entity_category") == "config" and component in ("sensor", "binary_sensor"):
        problems.append(f"{topic}: entity_category config on a read-only {component}")
    return problems


def check_limits(topic, document, metas):
    """A number's and a thermostat's range is the value's own limits (its /meta), or none."""
    component = component_of(topic)
    if component == "number":
        keys, state = ("min", "max"), document.get("state_topic")
    elif component == "climate":
        keys, state = ("min_temp", "max_temp"), document.get("temperature_state_topic")
    else:
        return []
    meta = metas.get(f"{state}/meta")
    if meta is None:
        return [f"{topic}: no retained {state}/meta to compare the range with"]
    problems = []
    for key, meta_key in zip(keys, ("min", "max")):
        limit = meta.get(meta_key)
        limit = limit if isinstance(limit, (int, float)) else None
        if document.get(key) != limit:
            problems.append(f"{topic}: {key} is {document.get(key)!r}, the device's limit is {limit!r}")
    low, high = document.get(keys[0]), document.get(keys[1])
    if low is not None and high is not None and not low < high:
        problems.append(f"{topic}: {keys[0]} is not below {keys[1]}")
    return problems


def accepted(component, key, document):
    """What a template's output may be for the platform: a function of the rendered text."""
    if key in ("current_temperature_template", "temperature_state_template"):
        return numeric
    if key == "mode_state_template":
        return lambda text: text in document.get("modes", ["heat"])
    if key == "preset_mode_value_template":
        return lambda text: text in document.get("preset_modes", [])
    if key == "action_template":
        return lambda text: text in HVAC_ACTIONS
    if component == "number":
        return numeric
    if component == "select" or (component == "sensor" and "options" in document):
        return lambda text: text in document.get("options", [])
    if component == "binary_sensor":
        return lambda text: text in (document.get("payload_on", "ON"), document.get("payload_off", "OFF"))
    if component == "sensor" and ("unit_of_measurement" in document or "state_class" in document):
        return numeric
    return lambda text: True


def state_topic_of(key, document):
    name = key[: -len("_template")]
    for topic_key in (f"{name}_topic", f"{name}_state_topic", "state_topic"):
        if topic_key in document:
            return document[topic_key]
    if key == "preset_mode_value_template":
        return document.get("preset_mode_state_topic")
    return None


def sample_values(key, document, states):
    """Real values to render a template with: the retained state, and what the platform's
    choices or a number make of it."""
    samples = []
    state = states.get(state_topic_of(key, document))
    if state is not None and state not in STATUS_WORDS:
        samples.append(state)
    component = component_of_document(document)
    if key == "value_template" and component == "binary_sensor" and "payload_on" in document:
        samples += [document["payload_on"], document["payload_off"]]
    elif key == "value_template" and "options" in document:
        samples += document["options"]
    elif key in ("preset_mode_value_template", "mode_state_template") and "preset_modes" in document:
        samples += document["preset_modes"]
    elif key == "value_template" and component == "binary_sensor":
        samples += ["{}", "{other}"]
    else:
        samples += ["21.5", "0", "-3.0"]
    return samples


def component_of_document(document):
    return document.get("_component")


def check_templates(topic, document, states, counts):
    problems = []
    component = component_of(topic)
    document = dict(document, _component=component)
    templates = {key: value for key, value in document.items() if key.endswith("_template") and "command" not in key}
    if component in ("number", "sensor", "select", "climate") and not templates and component != "sensor":
        problems.append(f"{topic}: no template maps a status word to unknown")
    if component == "sensor" and ("unit_of_measurement" in document or "options" in document) and "value_template" not in document:
        problems.append(f"{topic}: a numeric or enum sensor without a value_template")
    for key, template in templates.items():
        takes = accepted(component, key, document)
        counts["templates"] += 1
        for word in STATUS_WORDS:
            counts["renders"] += 1
            try:
                shown = render(template, word)
            except (jinja2.TemplateError, ValueError) as error:
                problems.append(f"{topic}: {key} fails on {word!r}: {error}")
                continue
            if shown not in (NONE, ""):
                problems.append(f"{topic}: {key} renders {word!r} as {shown!r}, not None (unknown)")
        for value in sample_values(key, document, states):
            counts["renders"] += 1
            try:
                shown = render(template, value)
            except (jinja2.TemplateError, ValueError) as error:
                problems.append(f"{topic}: {key} fails on {value!r}: {error}")
                continue
            if not takes(shown):
                problems.append(f"{topic}: {key} renders the value {value!r} as {shown!r}, which Home Assistant does not take")
    return problems


def check_bits(topic, document):
    """A bit of a field: the field's text naming it turns it on, one naming others leaves it off."""
    match = re.search(r'("(?:[^"\\]|\\.)*") in value', document.get("value_template", ""))
    if component_of(topic) != "binary_sensor" or not match:
        return []
    name = json.loads(match.group(1))
    problems = []
    for value, wanted in (("{other, " + name + "}", "ON"), ("{" + name + "_not}", "OFF"), ("{}", "OFF")):
        shown = render(document["value_template"], value)
        if shown != wanted:
            problems.append(f"{topic}: the bit template gives {shown!r} for {value!r}, not {wanted!r}")
    return problems


def check_mode_commands(topic, document):
    """A thermostat's mode commanded from Home Assistant reads back as that mode."""
    problems = []
    command, state = document.get("mode_command_template"), document.get("mode_state_template")
    if command is None or state is None:
        return problems
    for mode in document.get("modes", []):
        sent = render(command, mode)
        if sent not in document.get("preset_modes", []) or render(state, sent) != mode:
            problems.append(f"{topic}: mode {mode!r} is commanded as {sent!r}, which does not read back as {mode!r}")
    return problems


def main():
    arguments = [argument for argument in sys.argv[1:] if not argument.startswith("--expect=")]
    expectations = [argument[len("--expect="):] for argument in sys.argv[1:] if argument.startswith("--expect=")]
    port, discovery_prefix, state_prefix = int(arguments[0]), arguments[1], arguments[2]
    wanted = set(arguments[3:])
    gateway_id = re.sub(r"[^A-Za-z0-9_-]", "_", state_prefix.split("/")[-1])
    documents, states, metas = {}, {}, {}
    done = threading.Event()

    def on_message(client, userdata, message):
        text = message.payload.decode("utf-8", "replace")
        if message.topic.startswith(discovery_prefix + "/"):
            if message.retain and message.payload:
                documents[message.topic] = json.loads(text)
            elif not message.payload:
                documents.pop(message.topic, None)
        elif message.topic.endswith("/meta"):
            metas[message.topic] = json.loads(text)
        else:
            states[message.topic] = text
        if wanted <= {component_of(topic) for topic in documents}:
            done.set()

    client = mqtt.Client()
    client.on_message = on_message
    client.connect("127.0.0.1", port)
    client.subscribe(discovery_prefix + "/+/+/config", qos=1)
    client.subscribe(state_prefix + "/+/+", qos=1)
    client.subscribe(state_prefix + "/+/+/meta", qos=1)
    client.loop_start()
    done.wait(20)
    time.sleep(1.0)  # the rest of the retained documents and states
    client.loop_stop()
    problems = []
    found = {component_of(topic) for topic in documents}
    if not wanted <= found:
        problems.append(f"no document for {sorted(wanted - found)} (found {sorted(found)})")
    counts = {"templates": 0, "renders": 0}
    for topic, document in sorted(documents.items()):
        problems += check_schema(topic, document)
        problems += check_promises(topic, document, state_prefix, gateway_id)
        problems += check_limits(topic, document, metas)
        problems += check_templates(topic, document, states, counts)
        problems += check_bits(topic, document)
        problems += check_mode_commands(topic, document)
    # --expect=OBJECT_ID=KEY:JSON, KEY:absent or KEY:present: what a test asks of one document.
    for expectation in expectations:
        object_id, rest = expectation.split("=", 1)
        key, value = rest.split(":", 1)
        matching = [document for topic, document in documents.items() if topic.split("/")[-2] == object_id]
        if not matching:
            problems.append(f"--expect: no document {object_id}")
            continue
        present = key in matching[0]
        if value == "absent" and present:
            problems.append(f"{object_id}: {key} should be absent, is {matching[0][key]!r}")
        elif value == "present" and not present:
            problems.append(f"{object_id}: {key} should be present")
        elif value not in ("absent", "present") and (not present or matching[0][key] != json.loads(value)):
            problems.append(f"{object_id}: {key} should be {value}, is {matching[0].get(key, '(absent)')!r}")
    for problem in problems:
        print("FAIL", problem)
    print(f"{len(documents)} discovery documents checked, {counts['templates']} templates rendered against "
          f"{len(STATUS_WORDS)} status words and the values ({counts['renders']} renders), {len(problems)} problems")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
