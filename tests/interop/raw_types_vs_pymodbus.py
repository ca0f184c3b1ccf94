#!/usr/bin/python3
"""Typed raw reads (`read --type ... --word-order ...`) against a pymodbus RTU slave holding known
IEEE 754 and two's complement values in both word orders.

Usage: raw_types_vs_pymodbus.py LOOPWIRE

The slave's registers are packed here with Python's struct module, independently of loopwire's
decoder: each value big-endian (most significant register first) at one address and with its
registers reversed (least significant first) at another, and once with the bytes of each
register swapped. loopwire must print exactly the values packed, as JSON and as text, read
singly and several at once, and monitor them continuously.
"""

import json
import os
import struct
import subprocess
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import interop_support as support  # noqa: E402  pylint: disable=wrong-import-position

UNIT = 5

# (type, struct format, values). loopwire shows a float32 as the shortest decimal that reads back
# as the same float32: 0.1 (packed as 0x3DCCCCCD) must come back as 0.1, not 0.100000001490116.
VALUES = [
    ("float32", "f", [12.5, -3.25, 1e10, -0.0, 0.1, 273.15]),
    ("int32", "i", [123456789, -2, 2147483647, -2147483648, 0]),
    ("uint32", "I", [4000000000, 1, 65536]),
    ("float64", "d", [3.141592653589793, -1e-300, 0.1, 6.02214076e23]),
]
# Where each (type, word order) run of values starts.
BIG_AT = {"float32": 0, "int32": 100, "uint32": 200, "float64": 300}
LITTLE_AT = {"float32": 1000, "int32": 1100, "uint32": 1200, "float64": 1300}
BYTE_SWAPPED_FLOAT32_AT = 2000  # big word order, the bytes of every register swapped


def registers_of(fmt, value, order="big", byte_swap=False):
    raw = struct.pack(">" + fmt, value)
    words = [int.from_bytes(raw[i:i + 2], "big") for i in range(0, len(raw), 2)]
    if order == "little":
        words.reverse()
    if byte_swap:
        words = [((w & 0xFF) << 8) | (w >> 8) for w in words]
    return words


def preset_words():
    words = {}
    for name, fmt, values in VALUES:
        for start, order in ((BIG_AT[name], "big"), (LITTLE_AT[name], "little")):
            address = start
            for value in values:
                for word in registers_of(fmt, value, order):
                    words[address] = word
                    address += 1
    address = BYTE_SWAPPED_FLOAT32_AT
    for value in VALUES[0][2]:
        for word in registers_of("f", value, byte_swap=True):
            words[address] = word
            address += 1
    return words


def serve(path):
    from pymodbus.datastore import ModbusSequentialDataBlock, ModbusServerContext, ModbusSlaveContext
    from pymodbus.framer.rtu_framer import ModbusRtuFramer
    from pymodbus.server import StartSerialServer

    preset = preset_words()
    block = [preset.get(a, 0) for a in range(2100)]
    slave = ModbusSlaveContext(hr=ModbusSequentialDataBlock(0, block), ir=ModbusSequentialDataBlock(0, block), zero_mode=True)
    context = ModbusServerContext(slaves={UNIT: slave}, single=False)
    print(f"pymodbus typed-values slave: unit {UNIT} on {path}", flush=True)
    StartSerialServer(context=context, framer=ModbusRtuFramer, port=path, baudrate=19200, bytesize=8, parity="N", stopbits=1)


def shortest(value):
    """The text loopwire prints: Python's repr is the shortest round-trip form too, but of the
    double; for these values it is also the float32's. Integers as integers."""
    if isinstance(value, int):
        return str(value)
    text = repr(value)
    return text[:-2] if text.endswith(".0") else text


def test():
    loopwire = sys.argv[1]
    with support.Processes() as processes:
        slave_side, master_side = processes.socat_pair()
        processes.start(["timeout", str(support.PEER_LIFETIME_S), "/usr/bin/python3", os.path.abspath(__file__),
                         "--serve", slave_side], "pymodbus-server.log")
        support.wait_for_log(processes, "pymodbus-server.log", "typed-values slave")
        master = ["--link", f"rtu:{master_side}?baud=19200&parity=none", "--unit", str(UNIT), "--timeout", "500ms"]

        deadline = time.monotonic() + 10
        while subprocess.run([loopwire, "read", *master, "holding", "0"], capture_output=True, timeout=10, check=False).returncode:
            if time.monotonic() > deadline:
                raise support.TestFailure("the pymodbus server never answered")
            time.sleep(0.1)

        for name, fmt, values in VALUES:
            for start, order in ((BIG_AT[name], "big"), (LITTLE_AT[name], "little")):
                # All of a type at once: COUNT counts values.
                got = support.run_loopwire(loopwire, ["read", *master, "holding", str(start), str(len(values)), "--type", name,
                                                      "--word-order", order, "--json"])
                support.check_equal(got["values"], values, f"{name} {order} word order at {start}")
                support.check_equal(got["registers"], [w for v in values for w in registers_of(fmt, v, order)],
                                    f"{name} {order}: the registers pymodbus holds")
                # One at a time, as text: the value exactly as packed.
                each = len(registers_of(fmt, values[0]))
                for i, value in enumerate(values):
                    address = start + i * each
                    done = subprocess.run([loopwire, "read", *master, "input", str(address), "--type", name, "--word-order", order],
                                          capture_output=True, text=True, timeout=10, check=False)
                    lines = done.stdout.splitlines()
                    support.check_equal(lines[0].split(), ["address", name, "registers"], f"the column header of {name}")
                    shown = lines[1].split()
                    support.check_equal((done.returncode, shown[:2]), (0, [str(address), shortest(value)]),
                                        f"text of {name} {order} at input {address}")

        swapped = support.run_loopwire(loopwire, ["read", *master, "holding", str(BYTE_SWAPPED_FLOAT32_AT), str(len(VALUES[0][2])),
                                                  "--type", "float32", "--byte-swap", "--json"])
        support.check_equal(swapped["values"], VALUES[0][2], "float32 with the bytes of each register swapped")

        # The wrong word order gives other numbers: the test can tell the orders apart.
        wrong = support.run_loopwire(loopwire, ["read", *master, "holding", str(LITTLE_AT["int32"]), "--type", "int32", "--json"])
        support.check_equal(wrong["values"] != VALUES[1][2][:1], True, f"int32 little read as big: {wrong['values']}")

        # --base 1: register 1 is wire address 0.
        based = support.run_loopwire(loopwire, ["read", *master, "holding", "1", "--type", "float32", "--base", "1", "--json"])
        support.check_equal((based["address"], based["values"]), (1, [12.5]), "--base 1 reads wire address 0")

        # Continuous raw polling: three samples of the little-endian int32 values.
        done = subprocess.run([loopwire, "monitor", *master, "holding", str(LITTLE_AT["int32"]), str(len(VALUES[1][2])),
                               "--type", "int32", "--word-order", "little", "--count", "3", "--interval", "100ms",
                               "--format", "jsonl"], capture_output=True, text=True, timeout=20, check=False)
        rows = [json.loads(line) for line in done.stdout.splitlines() if line.strip()]
        support.check_equal((done.returncode, len(rows)), (0, 3), f"monitor took three samples: {done.stderr}")
        expected = {str(LITTLE_AT["int32"] + 2 * i): v for i, v in enumerate(VALUES[1][2])}
        for row in rows:
            support.check_equal((row["status"], row["values"]), ("ok", expected), f"monitor sample {row['sample']}")


if __name__ == "__main__":
    if len(sys.argv) == 3 and sys.argv[1] == "--serve":
        serve(sys.argv[2])
    else:
        support.main(test)
