#!/usr/bin/python3
"""pymodbus's TCP client with the RTU framer (RTU frames through a serial device server)
against `loopwire simulate --link rtu+tcp://127.0.0.1:0`.

Usage: pymodbus_rtu_over_tcp.py LOOPWIRE

No other peer here speaks RTU over TCP (libmodbus does not, PEERS.md). Unlike Modbus/TCP, the
frames carry a CRC and no MBAP header, and an unserved unit gets silence, as on a serial line.
"""

import os
import sys

from pymodbus.client import ModbusTcpClient
from pymodbus.framer.rtu_framer import ModbusRtuFramer

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import interop_support as support  # noqa: E402  pylint: disable=wrong-import-position


def test():
    loopwire = sys.argv[1]
    with support.Processes() as processes:
        # Port 0: loopwire takes a free port from the kernel and names it on stderr.
        processes.start([loopwire, "simulate", "--link", "rtu+tcp://127.0.0.1:0", "--unit", "3",
                         "--duration", f"{support.PEER_LIFETIME_S}s", "-v"], "simulate.log")
        port = int(support.wait_for_log(processes, "simulate.log", r"listening on port (\d+)").group(1))
        client = ModbusTcpClient("127.0.0.1", port=port, framer=ModbusRtuFramer, timeout=1, retries=0,
                                 retry_on_empty=False)
        if not client.connect():
            raise support.TestFailure(f"pymodbus cannot connect to port {port}")
        try:
            support.check_register_bank(client, 3, 5000)
            support.check_silent(client, 4)
        finally:
            client.close()
        # The frames really were RTU (unit, function, ..., CRC), not MBAP: the first request is
        # FC16 for unit 3 at address 5000 (1388h).
        support.check_equal("RX 03 10 13 88 00 05" in processes.log("simulate.log"), True,
                            "the trace shows an RTU frame for unit 3")


if __name__ == "__main__":
    support.main(test)
