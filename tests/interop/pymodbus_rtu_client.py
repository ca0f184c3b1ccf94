#!/usr/bin/python3
"""pymodbus's RTU client against `loopwire simulate --pty` serving units 1 and 2.

Usage: pymodbus_rtu_client.py LOOPWIRE

Checks that writes land in the addressed unit only, that untouched input registers and
discrete inputs read zero, and that a request for an unserved unit gets no reply at all
(Modbus over serial line V1.02, 2.2: only the addressed slave answers).
"""

import os
import sys
import time

from pymodbus.client import ModbusSerialClient
from pymodbus.framer.rtu_framer import ModbusRtuFramer

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import interop_support as support  # noqa: E402  pylint: disable=wrong-import-position


def test():
    loopwire = sys.argv[1]
    with support.Processes() as processes:
        pty = os.path.join(processes.tmp, "tty")
        # 8N1, not the 8E1 `--pty` alone would mean: Linux pseudo-terminals keep CS8 without parity
        # whatever is asked, and pyserial's tcsetattr() asking for even parity then fails with
        # EINVAL (always when pymodbus's strict mode reconfigures the open port, sometimes on
        # open). 8N1 asks only for what a pty keeps. With --pty the URL's path is not used.
        processes.start([loopwire, "simulate", "--link", "rtu:/unused?baud=19200&parity=none", "--pty", pty,
                         "--unit", "1", "--unit", "2",
                         "--duration", f"{support.PEER_LIFETIME_S}s", "-v"], "simulate.log")
        support.wait_for_path(pty)

        # retries=0: a missing reply must show up as a missing reply, not be papered over.
        # timeout=1: pymodbus 3.0.0rc1 truncates the timeout to whole seconds (0.5 becomes 0,
        # which makes every read return at once with nothing).
        client = ModbusSerialClient(port=pty, framer=ModbusRtuFramer, baudrate=19200, parity="N",
                                    bytesize=8, stopbits=1, timeout=1, retries=0, retry_on_empty=False)
        if not client.connect():
            raise support.TestFailure(f"pymodbus cannot open {pty}")
        try:
            # Holding registers: FC16 on both units with different values, then FC6 on unit 1.
            support.expect_reply(client.write_registers(10, [1111, 2222, 65535], slave=1), "FC16 unit 1")
            support.expect_reply(client.write_registers(10, [7, 8, 9], slave=2), "FC16 unit 2")
            support.expect_reply(client.write_register(11, 4242, slave=1), "FC6 unit 1")
            support.check_equal(support.expect_reply(client.read_holding_registers(10, 3, slave=1), "FC3 unit 1").registers,
                                [1111, 4242, 65535], "unit 1 holding 10..12")
            support.check_equal(support.expect_reply(client.read_holding_registers(10, 3, slave=2), "FC3 unit 2").registers,
                                [7, 8, 9], "unit 2 holding 10..12")
            # 125 registers is the most one FC3 may ask for (application protocol V1.1b3, 6.3).
            block = [(i * 517) & 0xFFFF for i in range(123)]
            support.expect_reply(client.write_registers(1000, block, slave=2), "FC16 123 registers unit 2")
            support.check_equal(support.expect_reply(client.read_holding_registers(999, 125, slave=2), "FC3 125").registers,
                                [0] + block + [0], "unit 2 holding 999..1123")

            # Coils: FC15 then FC5, across a byte boundary so the bit packing is exercised.
            pattern = [True, False, True, True, False, False, True, False, True, True]
            support.expect_reply(client.write_coils(20, pattern, slave=1), "FC15 unit 1")
            support.expect_reply(client.write_coil(21, True, slave=1), "FC5 unit 1")
            expected = list(pattern)
            expected[1] = True
            coils = support.expect_reply(client.read_coils(20, len(pattern), slave=1), "FC1 unit 1").bits[:len(pattern)]
            support.check_equal(coils, expected, "unit 1 coils 20..29")
            coils = support.expect_reply(client.read_coils(20, len(pattern), slave=2), "FC1 unit 2").bits[:len(pattern)]
            support.check_equal(coils, [False] * len(pattern), "unit 2 coils 20..29 (untouched)")

            # Tables nobody can write stay zero.
            support.check_equal(support.expect_reply(client.read_input_registers(0, 8, slave=1), "FC4").registers,
                                [0] * 8, "unit 1 input 0..7")
            support.check_equal(support.expect_reply(client.read_discrete_inputs(0, 12, slave=2), "FC2").bits[:12],
                                [False] * 12, "unit 2 discrete 0..11")

            # Unit 3 is not served: the simulator must stay silent.
            started = time.monotonic()
            response = client.read_holding_registers(10, 1, slave=3)
            waited = time.monotonic() - started
            if not response.isError():
                raise support.TestFailure(f"unit 3 is not served but answered: {response}")
            print(f"ok: unit 3 got no reply ({response}) after {waited:.2f} s")

            # And the line still works afterwards.
            support.check_equal(support.expect_reply(client.read_holding_registers(10, 1, slave=1), "FC3 after silence")
                                .registers, [1111], "unit 1 holding 10 after the unserved request")
        finally:
            client.close()

        log = processes.log("simulate.log")
        if "unit 3" not in log:
            raise support.TestFailure(f"the simulator's trace does not show the request for unit 3:\n{log}")
        support.check_equal(log.count(" TX "), 14, "replies the simulator sent (one per request but unit 3's)")


if __name__ == "__main__":
    support.main(test)
