#!/usr/bin/python3
"""Named read/write and scan (device profiles) against a pymodbus RTU slave loaded like a TC10.

Usage: named_access_vs_pymodbus.py LOOPWIRE

The slave holds words a TC10 would (its manual §5): measured value 1234 with dP = 1 (123.4),
instrument id 20 at word 21, SP.LL 0, SP.HL 2000 (200.0) and SP 500 (50.0), and 10000 (the
manual's out-of-range code) in the measured value copy at 512. loopwire reads them by name in
engineering units, writes SP within its limits and is refused above SP.HL before anything is
sent, and `scan` finds unit 7 and identifies it as a TC10.
"""

import os
import subprocess
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import interop_support as support  # noqa: E402  pylint: disable=wrong-import-position

UNIT = 7
PRESET = {1: 1234, 20: 0x0102, 21: 20, 512: 10000, 641: 1, 715: 0, 716: 2000, 717: 500}


def serve(path):
    from pymodbus.datastore import ModbusSequentialDataBlock, ModbusServerContext, ModbusSlaveContext
    from pymodbus.framer.rtu_framer import ModbusRtuFramer
    from pymodbus.server import StartSerialServer

    words = [PRESET.get(a, 0) for a in range(1000)]
    slave = ModbusSlaveContext(hr=ModbusSequentialDataBlock(0, words), zero_mode=True)
    context = ModbusServerContext(slaves={UNIT: slave}, single=False)
    print(f"pymodbus TC10-like slave: unit {UNIT} on {path}", flush=True)
    StartSerialServer(context=context, framer=ModbusRtuFramer, port=path, baudrate=19200, bytesize=8, parity="N", stopbits=1)


def test():
    loopwire = sys.argv[1]
    with support.Processes() as processes:
        slave_side, master_side = processes.socat_pair()
        processes.start(["timeout", str(support.PEER_LIFETIME_S), "/usr/bin/python3", os.path.abspath(__file__),
                         "--serve", slave_side], "pymodbus-server.log")
        support.wait_for_log(processes, "pymodbus-server.log", "TC10-like slave")
        link = ["--link", f"rtu:{master_side}?baud=19200&parity=none", "--timeout", "500ms"]
        device = ["--device", f"tc10@{UNIT}"]

        values = support.run_loopwire(loopwire, ["read", *link, *device, "measured_value", "SP", "sp.ll", "measured_value_b", "--json"])["values"]
        support.check_equal(values["measured_value"], {"value": 123.4, "raw": 1234, "unit": values["measured_value"]["unit"], "status": "ok",
                                                       "text": "123.4", "min": None, "max": None}, "measured value with dP = 1")
        support.check_equal(values["set_point"]["value"], 50.0, "SP by mnemonic")
        # Its limits as numbers, read from SP.LL and SP.HL (2000 at one decimal).
        support.check_equal((values["set_point"]["min"], values["set_point"]["max"]), (0.0, 200.0), "SP's limits from SP.LL/SP.HL")
        support.check_equal(values["set_point_low_limit"]["value"], 0.0, "SP.LL, mnemonic in lower case")
        support.check_equal((values["measured_value_b"]["value"], values["measured_value_b"]["status"]), (None, "out-of-range"),
                            "10000 decoded as a special state")

        support.run_loopwire(loopwire, ["write", *link, *device, "SP=150.5", "--json"])
        after = support.run_loopwire(loopwire, ["read", *link, *device, "set_point", "--json"])["values"]["set_point"]
        support.check_equal((after["value"], after["raw"]), (150.5, 1505), "SP written in engineering units")

        refused = subprocess.run([loopwire, "write", *link, *device, "SP=250"], capture_output=True, text=True, timeout=10, check=False)
        support.check_equal(refused.returncode, 2, "a write above SP.HL is a usage error")
        support.check_equal("set_point_high_limit" in refused.stderr, True, "the refusal names the limit: " + refused.stderr.strip())
        unchanged = support.run_loopwire(loopwire, ["read", *link, *device, "set_point", "--json"])["values"]["set_point"]
        support.check_equal(unchanged["raw"], 1505, "a refused write sends nothing")

        found = support.run_loopwire(loopwire, ["scan", "--link", f"rtu:{master_side}?baud=19200&parity=none",
                                                "--units", "5-8", "--timeout", "200ms", "--json"])["units"]
        support.check_equal([(u["unit"], u["device"]) for u in found], [(UNIT, "tc10")], "scan finds and identifies the unit")


if __name__ == "__main__":
    if len(sys.argv) == 3 and sys.argv[1] == "--serve":
        serve(sys.argv[2])
    else:
        support.main(test)
