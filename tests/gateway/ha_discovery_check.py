"""An independent MQTT client (paho) reads the gateway's Home Assistant discovery documents and
checks each against what Home Assistant's MQTT integration documents for its component: the
required keys, the type of every key used, and what the gateway promises besides (availability
on both the gateway's and the device's status, unique ids, a device block from the profile).

Written from Home Assistant's documentation pages for MQTT discovery and the MQTT sensor,
binary sensor, number, select and climate (HVAC) platforms, and its entity categories. A binary
sensor's value_template is rendered with Jinja2 (Home Assistant's template engine) against the
state the gateway published, and must give the sensor's payload_on or payload_off.

usage: ha_discovery_check.py PORT DISCOVERY_PREFIX STATE_PREFIX COMPONENT...
Exits 0 when a document of each COMPONENT came and every document passed; prints what failed.
"""
import json
import re
import sys
import threading
import time

import jinja2
import paho.mqtt.client as mqtt

STRING = str
NUMBER = (int, float)
LIST = list
DICT = dict

# Keys every entity may carry (the shared "availability", "device", ... options), with types.
COMMON = {
    "name": STRING, "unique_id": STRING, "state_topic": STRING, "device": DICT, "availability": LIST,
    "availability_mode": STRING, "unit_of_measurement": STRING, "value_template": STRING,
    "device_class": STRING, "icon": STRING, "entity_category": STRING, "qos": int,
}
# Per component: required keys and the keys it adds.
PLATFORMS = {
    "sensor": ({"state_topic"}, {"state_class": STRING, "suggested_display_precision": int, "options": LIST}),
    "binary_sensor": ({"state_topic"}, {"payload_on": STRING, "payload_off": STRING}),
    "number": ({"command_topic"}, {"command_topic": STRING, "min": NUMBER, "max": NUMBER, "step": NUMBER,
                                    "mode": STRING, "command_template": STRING}),
    "select": ({"command_topic", "options"}, {"command_topic": STRING, "options": LIST, "command_template": STRING}),
    # The MQTT climate platform (HVAC): no state_topic of its own, a topic per temperature.
    "climate": ({"current_temperature_topic", "temperature_state_topic"},
                {"current_temperature_topic": STRING, "current_temperature_template": STRING,
                 "temperature_state_topic": STRING, "temperature_state_template": STRING,
                 "temperature_command_topic": STRING, "temperature_unit": STRING, "min_temp": NUMBER,
                 "max_temp": NUMBER, "temp_step": NUMBER, "precision": NUMBER, "modes": LIST,
                 "mode_state_topic": STRING, "mode_state_template": STRING, "mode_command_topic": STRING,
                 "mode_command_template": STRING, "preset_modes": LIST, "preset_mode_state_topic": STRING,
                 "preset_mode_command_topic": STRING}),
}
# Entity categories Home Assistant knows; `config` only on entities that change something.
CATEGORIES = {"config", "diagnostic"}
READ_ONLY = {"sensor", "binary_sensor"}
# The binary sensor device classes this gateway uses, from Home Assistant's list.
BINARY_CLASSES = {"problem", "safety", "running", "heat", "power"}
# Home Assistant's temperature device class takes these units only; climate's unit is C or F.
TEMPERATURE_UNITS = {"°C", "°F", "K"}
DEVICE_KEYS = {"identifiers": LIST, "name": STRING, "manufacturer": STRING, "model": STRING}
AVAILABILITY_KEYS = {"topic": STRING, "payload_available": STRING, "payload_not_available": STRING, "value_template": STRING}
OBJECT_ID = re.compile(r"^[A-Za-z0-9_-]+$")
BIT_IN_TEMPLATE = re.compile(r'("(?:[^"\\]|\\.)*") in value')


def check_types(where, document, allowed, problems):
    for key, value in document.items():
        if key not in allowed:
            problems.append(f"{where}: unknown key {key!r}")
        elif not isinstance(value, allowed[key]) or isinstance(value, bool) and allowed[key] is not bool:
            problems.append(f"{where}: {key} has the wrong type ({type(value).__name__})")


def check(topic, document, state_prefix):
    problems = []
    parts = topic.split("/")
    component, object_id = parts[-3], parts[-2]
    if component not in PLATFORMS:
        return [f"{topic}: unexpected component {component}"]
    required, extra = PLATFORMS[component]
    allowed = dict(COMMON, **extra)
    check_types(topic, document, allowed, problems)
    own_state = "temperature_state_topic" if component == "climate" else "state_topic"
    for key in required | {"unique_id", own_state, "device", "availability"}:
        if key not in document:
            problems.append(f"{topic}: missing {key}")
    if not OBJECT_ID.match(object_id) or document.get("unique_id") != object_id:
        problems.append(f"{topic}: object id {object_id!r} is not the unique_id or not [A-Za-z0-9_-]")
    device = document.get("device", {})
    check_types(topic + " device", device, DEVICE_KEYS, problems)
    if not device.get("identifiers") or not device.get("model"):
        problems.append(f"{topic}: the device block needs identifiers and a model")
    availability = document.get("availability", [])
    for entry in availability:
        check_types(topic + " availability", entry, AVAILABILITY_KEYS, problems)
        if entry.get("payload_available") != "online":
            problems.append(f"{topic}: availability payload_available is not online")
    topics = [entry.get("topic") for entry in availability]
    state_topic = document.get(own_state, "")
    device_availability = "/".join(state_topic.split("/")[:-1]) + "/availability"
    if topics != [state_prefix + "/status", device_availability] or document.get("availability_mode") != "all":
        problems.append(f"{topic}: availability should be the gateway's status and the device's availability, mode all: {topics}")
    if not state_topic.startswith(state_prefix + "/"):
        problems.append(f"{topic}: {own_state} outside {state_prefix}")
    if document.get("device_class") == "temperature" and document.get("unit_of_measurement") not in TEMPERATURE_UNITS:
        problems.append(f"{topic}: a temperature in {document.get('unit_of_measurement')!r}, not one of {sorted(TEMPERATURE_UNITS)}")
    if component == "climate":
        if document.get("temperature_unit") not in ("C", "F"):
            problems.append(f"{topic}: temperature_unit must be C or F")
        if not document.get("min_temp", 0) < document.get("max_temp", 0):
            problems.append(f"{topic}: min_temp is not below max_temp")
        if document.get("precision") not in (0.1, 0.5, 1.0):
            problems.append(f"{topic}: precision must be 0.1, 0.5 or 1.0")
        command = document.get("temperature_command_topic")
        if command is not None and command != state_topic + "/set":
            problems.append(f"{topic}: temperature_command_topic is not TEMPERATURE_STATE_TOPIC/set")
    category = document.get("entity_category")
    if category is not None and (category not in CATEGORIES or (category == "config" and component in READ_ONLY)):
        problems.append(f"{topic}: entity_category {category!r} is not one Home Assistant takes on a {component}")
    if component == "binary_sensor" and document.get("device_class") not in (None, *BINARY_CLASSES):
        problems.append(f"{topic}: {document.get('device_class')!r} is no binary sensor device class")
    if component in ("number", "select") and document.get("command_topic") != document.get("state_topic") + "/set":
        problems.append(f"{topic}: command_topic is not STATE_TOPIC/set")
    if component == "number" and not document.get("min", 0) < document.get("max", 0):
        problems.append(f"{topic}: min is not below max")
    if component == "select" and not all(isinstance(option, str) for option in document.get("options", [None])):
        problems.append(f"{topic}: options must be strings")
    return problems


def check_template(topic, document, states):
    """A binary sensor's template turns the published state into its payload_on or payload_off."""
    template = document.get("value_template")
    state = states.get(document.get("state_topic"))
    if template is None:
        return []
    if state is None:
        return [f"{topic}: no retained state on {document.get('state_topic')} to render value_template against"]
    on, off = document.get("payload_on", "ON"), document.get("payload_off", "OFF")
    # A bit of a field ("... if \"alarm_1\" in value ..."): a field's text naming that bit
    # among others turns it on, one naming others only leaves it off.
    bit = BIT_IN_TEMPLATE.search(template)
    cases = [(state, {on, off})]
    if bit:
        name = json.loads(bit.group(1))
        cases += [("{other, " + name + "}", {on}), ("{" + name + "_not}", {off}), ("{}", {off})]
    problems = []
    for value, allowed in cases:
        try:
            shown = render(template, value)
        except jinja2.TemplateError as error:
            return [f"{topic}: value_template does not render: {error}"]
        if shown not in allowed:
            problems.append(f"{topic}: value_template gave {shown!r} for {value!r}, not one of {sorted(allowed)}")
    return problems


# Home Assistant's HVAC modes; presets are the device's own words, never "none".
HVAC_MODES = {"auto", "off", "cool", "heat", "dry", "fan_only", "heat_cool"}


def render(template, value):
    return jinja2.Environment().from_string(template).render(value=value).strip()


def check_climate_modes(topic, document, states):
    """The thermostat's mode templates map the device's mode word and back, as HA would run them."""
    problems = []
    modes, presets = document.get("modes", []), document.get("preset_modes", [])
    if not set(modes) <= HVAC_MODES:
        problems.append(f"{topic}: modes {modes} are not all Home Assistant HVAC modes")
    if "none" in presets:
        problems.append(f"{topic}: 'none' is not a preset Home Assistant takes")
    state_template = document.get("mode_state_template")
    if state_template is None:
        return problems
    if document.get("mode_state_topic") not in states:
        problems.append(f"{topic}: no retained state on {document.get('mode_state_topic')} for the mode")
    for preset in presets + [states.get(document.get("mode_state_topic"), presets[0] if presets else "")]:
        if render(state_template, preset) not in modes:
            problems.append(f"{topic}: mode_state_template gives {render(state_template, preset)!r} for {preset!r}")
    command_template = document.get("mode_command_template")
    if command_template is not None:
        for mode in modes:
            sent = render(command_template, mode)
            if sent not in presets or render(state_template, sent) != mode:
                problems.append(f"{topic}: mode {mode!r} is commanded as {sent!r}, which does not read back as {mode!r}")
    return problems


def main():
    port, discovery_prefix, state_prefix = int(sys.argv[1]), sys.argv[2], sys.argv[3]
    wanted = set(sys.argv[4:])
    documents = {}
    done = threading.Event()

    states = {}

    def on_message(client, userdata, message):
        if not message.topic.startswith(discovery_prefix + "/"):
            states[message.topic] = message.payload.decode("utf-8", "replace")
            return
        if message.retain and message.payload:
            documents[message.topic] = json.loads(message.payload)
        if wanted <= {topic.split("/")[-3] for topic in documents}:
            done.set()

    client = mqtt.Client()
    client.on_message = on_message
    client.connect("127.0.0.1", port)
    client.subscribe(discovery_prefix + "/+/+/config", qos=1)
    client.subscribe(state_prefix + "/+/+", qos=1)
    client.loop_start()
    done.wait(20)
    time.sleep(0.5)  # the rest of the retained documents
    client.loop_stop()
    problems = []
    found = {topic.split("/")[-3] for topic in documents}
    if not wanted <= found:
        problems.append(f"no document for {sorted(wanted - found)} (found {sorted(found)})")
    for topic, document in sorted(documents.items()):
        problems += check(topic, document, state_prefix)
        if topic.split("/")[-3] == "binary_sensor":
            problems += check_template(topic, document, states)
        if topic.split("/")[-3] == "climate":
            problems += check_climate_modes(topic, document, states)
    templates = sum(1 for document in documents.values() if "value_template" in document and document.get("state_topic") in states)
    for problem in problems:
        print("FAIL", problem)
    print(f"{len(documents)} discovery documents checked ({templates} with a template and a state), {len(problems)} problems")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
