#!/usr/bin/python3
"""`loopwire read` / `loopwire write` against a pymodbus serial slave across a socat pty pair.

Usage: loopwire_vs_pymodbus_serial_server.py LOOPWIRE rtu|ascii

RTU runs as 19200 8N1; ASCII as its usual 7E1 on loopwire's side (pymodbus opens its end 8N1:
see pymodbus_ascii_client.py for why; the pty carries bytes either way).

Reads compare loopwire's --json output with the slave's known contents; writes are read back
by loopwire and, independently, by a pymodbus client, so a mistake that loopwire makes the
same way in both directions cannot hide. Also: an exception reply (exit 5) and a silent unit
(exit 4, within a short --timeout).
"""

import os
import subprocess
import sys
import time

from pymodbus.client import ModbusSerialClient
from pymodbus.framer.ascii_framer import ModbusAsciiFramer
from pymodbus.framer.rtu_framer import ModbusRtuFramer

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import interop_support as support  # noqa: E402  pylint: disable=wrong-import-position
import pymodbus_serial_server as server  # noqa: E402  pylint: disable=wrong-import-position

UNIT = 5


def expected(preset, address, count):
    return [int(preset(a)) for a in range(address, address + count)]


def test():
    loopwire, framing = sys.argv[1], sys.argv[2]
    settings = {"rtu": "baud=19200&parity=none", "ascii": "baud=19200&parity=even&data=7"}[framing]
    with support.Processes() as processes:
        slave_side, master_side = processes.socat_pair()
        processes.start(["timeout", str(support.PEER_LIFETIME_S), "/usr/bin/python3",
                         os.path.join(os.path.dirname(os.path.abspath(__file__)), "pymodbus_serial_server.py"),
                         slave_side, str(UNIT), framing], "pymodbus-server.log")
        link = f"{framing}:{master_side}?{settings}"
        master = ["--link", link, "--unit", str(UNIT), "--timeout", "300ms", "--retries", "0"]

        def read(table, address, count, expect_exit=0):
            return support.run_loopwire(loopwire, ["read", *master, table, str(address), str(count), "--json"],
                                        expect_exit=expect_exit)

        def write(table, address, values, *extra):
            return support.run_loopwire(loopwire, ["write", *master, table, str(address),
                                                   *[str(v) for v in values], *extra, "--json"])

        # The server needs a moment to import pymodbus and open its port; ask until it answers.
        deadline = time.monotonic() + 10
        while True:
            probe = subprocess.run([loopwire, "read", *master, "holding", "0", "1"],
                                   capture_output=True, text=True, timeout=10, check=False)
            if probe.returncode == 0:
                break
            if time.monotonic() > deadline:
                raise support.TestFailure(f"the pymodbus server never answered: {probe.stderr}")
            time.sleep(0.1)

        # Reads of every table, exact JSON.
        support.check_equal(read("holding", 0, 10),
                            {"unit": UNIT, "table": "holding", "address": 0,
                             "values": expected(server.holding_preset, 0, 10)}, "read holding 0 10")
        # 130 registers: more than one FC3 may carry, so loopwire splits it (125 + 5).
        support.check_equal(read("holding", 50, 130)["values"], expected(server.holding_preset, 50, 130),
                            "read holding 50 130")
        support.check_equal(read("input", 190, 10)["values"], expected(server.input_preset, 190, 10),
                            "read input 190 10 (last entries)")
        support.check_equal(read("coils", 0, 19)["values"], expected(server.coil_preset, 0, 19),
                            "read coils 0 19")
        support.check_equal(read("discrete", 7, 12)["values"], expected(server.discrete_preset, 7, 12),
                            "read discrete 7 12")

        # Past the end of the slave's tables: exception 2 -> exit 5.
        read("holding", server.TABLE_SIZE - 2, 3, expect_exit=5)
        read("input", server.TABLE_SIZE, 1, expect_exit=5)

        # Writes: FC6, FC16, FC16 forced for one value, FC5, FC15; negative values go out as
        # two's complement.
        support.check_equal(write("holding", 20, [4242]),
                            {"unit": UNIT, "table": "holding", "address": 20, "values": [4242], "broadcast": False},
                            "write holding 20 4242")
        write("holding", 30, [1, 65535, -2, 0x1234])
        write("holding", 40, [77], "--multiple")
        write("coils", 1, [1])
        write("coils", 100, [1, 0, 1, 1, 0, 0, 1, 1, 1])
        support.check_equal(read("holding", 20, 1)["values"], [4242], "read back holding 20")
        support.check_equal(read("holding", 30, 4)["values"], [1, 65535, 65534, 0x1234], "read back holding 30..33")
        support.check_equal(read("holding", 40, 1)["values"], [77], "read back holding 40")
        support.check_equal(read("coils", 0, 3)["values"], [1, 1, 0], "read back coils 0..2")
        support.check_equal(read("coils", 100, 9)["values"], [1, 0, 1, 1, 0, 0, 1, 1, 1], "read back coils 100..108")

        # Writing past the end: exception too.
        support.run_loopwire(loopwire, ["write", *master, "holding", str(server.TABLE_SIZE - 1), "1", "2"], expect_exit=5)

        # A unit the slave does not serve: silence -> exit 4, and promptly.
        started = time.monotonic()
        support.run_loopwire(loopwire, ["read", "--link", link, "--unit", str(UNIT + 1), "--timeout", "300ms",
                                        "--retries", "0", "holding", "0", "1"], expect_exit=4)
        waited = time.monotonic() - started
        if waited > 2.0:
            raise support.TestFailure(f"a 300 ms timeout took {waited:.2f} s to report")

        # An independent reader: pymodbus itself sees what loopwire wrote (timeout in whole
        # seconds: pymodbus 3.0.0rc1 truncates it to an int).
        framer = {"rtu": ModbusRtuFramer, "ascii": ModbusAsciiFramer}[framing]
        client = ModbusSerialClient(port=master_side, framer=framer, baudrate=19200, parity="N",
                                    bytesize=8, stopbits=1, timeout=1, retries=0)
        if not client.connect():
            raise support.TestFailure(f"pymodbus cannot open {master_side}")
        try:
            support.check_equal(client.read_holding_registers(30, 4, slave=UNIT).registers,
                                [1, 65535, 65534, 0x1234], "pymodbus reads holding 30..33")
            support.check_equal(client.read_holding_registers(20, 1, slave=UNIT).registers, [4242],
                                "pymodbus reads holding 20")
            support.check_equal(client.read_coils(100, 9, slave=UNIT).bits[:9],
                                [True, False, True, True, False, False, True, True, True], "pymodbus reads coils 100..108")
        finally:
            client.close()


if __name__ == "__main__":
    support.main(test)
