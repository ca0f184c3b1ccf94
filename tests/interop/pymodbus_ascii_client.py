#!/usr/bin/python3
"""pymodbus's ASCII client against `loopwire simulate` serving Modbus ASCII on a pseudo-terminal.

Usage: pymodbus_ascii_client.py LOOPWIRE

loopwire serves the usual ASCII line format, 9600 7E1 (Modbus over serial line V1.02, 2.5.2).
pymodbus opens the pty as 8N1: Linux pseudo-terminals carry whole bytes and keep CS8 without
parity whatever is asked, and glibc's tcsetattr() reports EINVAL for a request whose only
changes are those refused bits, so a 7E1 open works or fails depending on what the pty was
set to before. 8N1 always works, and ASCII frames are 7-bit characters either way; loopwire
with data=7 ignores the eighth bit, pymodbus sends it as zero.
"""

import os
import sys

from pymodbus.client import ModbusSerialClient
from pymodbus.framer.ascii_framer import ModbusAsciiFramer

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import interop_support as support  # noqa: E402  pylint: disable=wrong-import-position


def test():
    loopwire = sys.argv[1]
    with support.Processes() as processes:
        pty = os.path.join(processes.tmp, "tty")
        # With --pty the URL gives only framing and settings; its path is not used.
        processes.start([loopwire, "simulate", "--link", "ascii:/unused?baud=9600&parity=even&data=7", "--pty", pty,
                         "--unit", "17", "--duration", f"{support.PEER_LIFETIME_S}s", "-v"], "simulate.log")
        support.wait_for_path(pty)
        # timeout=1: pymodbus 3.0.0rc1 truncates the timeout to whole seconds.
        client = ModbusSerialClient(port=pty, framer=ModbusAsciiFramer, baudrate=9600, bytesize=8, parity="N",
                                    stopbits=1, timeout=1, retries=0, retry_on_empty=False)
        if not client.connect():
            raise support.TestFailure(f"pymodbus cannot open {pty}")
        try:
            support.check_register_bank(client, 17, 300)
            support.check_silent(client, 18)
            support.check_equal(support.expect_reply(client.read_holding_registers(300, 1, slave=17), "FC3").registers,
                                [300], "holding 300 after the unserved request")
        finally:
            client.close()
        # The frames really were ASCII: each request in the trace starts with ':' (3A).
        requests = [line for line in processes.log("simulate.log").splitlines() if " RX " in line]
        if not requests or not all(line.split(" RX ")[1].startswith("3A ") for line in requests):
            raise support.TestFailure(f"not every request in the trace is an ASCII frame:\n{processes.log('simulate.log')}")
        print(f"ok: all {len(requests)} requests were ASCII frames")


if __name__ == "__main__":
    support.main(test)
