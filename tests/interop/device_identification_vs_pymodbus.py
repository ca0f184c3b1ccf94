#!/usr/bin/python3
"""Read Device Identification (function 43, MEI type 14): loopwire against pymodbus's serial slave.

Usage: device_identification_vs_pymodbus.py LOOPWIRE
       device_identification_vs_pymodbus.py serve SERIAL_PATH UNIT   (the slave, started by the test)

The slave has an identity of all seven regular objects, two of them long enough that the regular
objects do not fit one reply: pymodbus then sends them in two parts (more follows, next object
id), which loopwire must follow. `loopwire describe --link` and `loopwire scan` must show each
object as pymodbus holds it; a unit pymodbus does not serve stays silent and is not found.
"""

import os
import subprocess
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import interop_support as support  # noqa: E402  pylint: disable=wrong-import-position

UNIT = 4
IDENTITY = {
    "VendorName": "loopwire interop",
    "ProductCode": "LW-43-14",
    "MajorMinorRevision": "2.7",
    "VendorUrl": "https://example.org/loopwire",
    "ProductName": "identity test slave",
    # Together past the 247 bytes one reply carries: the rest follows in a second reply.
    "ModelName": "M" * 120,
    "UserApplicationName": "U" * 120,
}
BASIC = ["VendorName", "ProductCode", "MajorMinorRevision"]


def serve(path, unit):
    from pymodbus.datastore import ModbusSequentialDataBlock, ModbusServerContext, ModbusSlaveContext
    from pymodbus.device import ModbusDeviceIdentification
    from pymodbus.framer.rtu_framer import ModbusRtuFramer
    from pymodbus.server import StartSerialServer

    slave = ModbusSlaveContext(hr=ModbusSequentialDataBlock(0, [7] * 10), zero_mode=True)
    context = ModbusServerContext(slaves={unit: slave}, single=False)
    identity = ModbusDeviceIdentification(info_name=IDENTITY)
    print(f"pymodbus rtu server with identity: unit {unit} on {path}", flush=True)
    StartSerialServer(context=context, identity=identity, framer=ModbusRtuFramer, port=path, baudrate=19200,
                      bytesize=8, parity="N", stopbits=1)


def test():
    loopwire = sys.argv[1]
    with support.Processes() as processes:
        slave_side, master_side = processes.socat_pair()
        processes.start(["timeout", str(support.PEER_LIFETIME_S), "/usr/bin/python3", os.path.abspath(__file__), "serve",
                         slave_side, str(UNIT)], "pymodbus-server.log")
        link = f"rtu:{master_side}?baud=19200&parity=none"
        # The server needs a moment to import pymodbus and open its port; ask until it answers.
        deadline = time.monotonic() + 10
        while True:
            probe = subprocess.run([loopwire, "read", "--link", link, "--unit", str(UNIT), "holding", "0", "1"],
                                   capture_output=True, text=True, timeout=10, check=False)
            if probe.returncode == 0:
                break
            if time.monotonic() > deadline:
                raise support.TestFailure(f"the pymodbus server never answered: {probe.stderr}")
            time.sleep(0.1)

        described = support.run_loopwire(loopwire, ["describe", "--link", link, "--unit", str(UNIT), "--timeout", "1s",
                                                    "--json"])
        support.check_equal(described, {"unit": UNIT, "device_identity": IDENTITY}, "describe --link --json")

        text = subprocess.run([loopwire, "describe", "--link", link, "--unit", str(UNIT)], capture_output=True, text=True,
                              timeout=10, check=False)
        if text.returncode != 0 or "VendorName" not in text.stdout or IDENTITY["ProductCode"] not in text.stdout:
            raise support.TestFailure(f"describe --link: exit {text.returncode}\n{text.stdout}\n{text.stderr}")

        scanned = support.run_loopwire(loopwire, ["scan", "--link", link, "--units", f"{UNIT - 1}-{UNIT + 1}",
                                                  "--timeout", "300ms", "--json"], timeout_s=30)
        support.check_equal([unit["unit"] for unit in scanned["units"]], [UNIT], "units scan found")
        support.check_equal(scanned["units"][0]["device_identity"], IDENTITY, "scan's device_identity")
        support.check_equal(list(scanned["units"][0]["device_identity"])[:3], BASIC, "the basic objects come first")


if __name__ == "__main__":
    if len(sys.argv) == 4 and sys.argv[1] == "serve":
        serve(sys.argv[2], int(sys.argv[3]))
    else:
        support.main(test)
