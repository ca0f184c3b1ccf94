#!/usr/bin/python3
"""pymodbus's RTU client drives each simulated controller (`loopwire simulate --device`) over a
pseudo-terminal and finds the behaviour each manual describes.

Usage: simulators_vs_pymodbus.py LOOPWIRE ac20|tc10|rampsoak

The link is 8N1 whatever the device's own byte format (Linux pseudo-terminals keep no parity;
PEERS.md): the simulator warns and serves.
"""

import os
import sys
import time

from pymodbus.client import ModbusSerialClient
from pymodbus.framer.rtu_framer import ModbusRtuFramer
from pymodbus.other_message import ReportSlaveIdRequest
from pymodbus.pdu import ExceptionResponse

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import interop_support as support  # noqa: E402  pylint: disable=wrong-import-position

UNIT = 4


def exception_code(response, what):
    if not isinstance(response, ExceptionResponse):
        raise support.TestFailure(f"{what}: expected an exception reply, got {response}")
    print(f"ok: {what} -> exception {response.exception_code}")
    return response.exception_code


def check_silence(client, what, request):
    started = time.monotonic()
    response = request()
    if not response.isError() or isinstance(response, ExceptionResponse):
        raise support.TestFailure(f"{what}: expected no reply, got {response}")
    print(f"ok: {what} -> no reply after {time.monotonic() - started:.2f} s")


def registers(client, address, count, what):
    return support.expect_reply(client.read_holding_registers(address, count, slave=UNIT), what).registers


def check_ac20(client):
    """ac20-modbus-jbus-eng824e.en.txt"""
    support.check_equal(registers(client, 120, 1, "identification word 120"), [50], "AC20 word 120 (device code)")
    # Error reply: at most 20 words per request, error 9 beyond.
    support.check_equal(len(registers(client, 120, 20, "20 words")), 20, "20 words in one FC3")
    support.check_equal(exception_code(client.read_holding_registers(120, 21, slave=UNIT), "21 words"), 9, "error 9")
    # Error reply: no reply for a function code the AC20 does not implement (FC 17 here).
    check_silence(client, "FC17 (not implemented)", lambda: client.execute(ReportSlaveIdRequest(unit=UNIT)))
    # Note 5: in local only bit 218 may be written (error 10 for the rest); remote lets SP in.
    support.check_equal(exception_code(client.write_register(138, 5, slave=UNIT), "SP in local"), 10, "error 10 in local")
    support.expect_reply(client.write_coil(218, True, slave=UNIT), "bit 218 = remote")
    support.expect_reply(client.write_register(138, 5, slave=UNIT), "SP in remote")
    support.check_equal(registers(client, 138, 1, "SP back"), [5], "main set point after the write")
    # Note 5: more than 3 s without line activity and the device is back in local.
    time.sleep(3.5)
    bits = support.expect_reply(client.read_coils(218, 1, slave=UNIT), "bit 218 after 3.5 s").bits[0]
    support.check_equal(bits, False, "bit 218 after 3.5 s of silence (local again)")


def check_tc10(client):
    """tc10-modbus-im05c01e81-03.ru.txt"""
    support.check_equal(registers(client, 21, 1, "word 21"), [20], "TC10 word 21 (instrument id)")
    support.expect_reply(client.write_register(717, 150, slave=UNIT), "SP = 150")
    support.check_equal(registers(client, 717, 1, "SP"), [150], "SP at 717")
    support.check_equal(registers(client, 717 + 9600, 1, "SP mirror"), [150], "SP at 10317 (§5: both ranges)")
    # §3.1/3.3: at most 16 registers; §3.4: exception 1 for other function codes.
    support.check_equal(exception_code(client.read_holding_registers(640, 17, slave=UNIT), "17 registers"), 3, "exception 3")
    support.check_equal(exception_code(client.read_input_registers(1, 1, slave=UNIT), "FC4"), 1, "exception 1")
    # §4.4 B: a value outside the parameter's range is refused and memory stays as it was.
    support.expect_reply(client.write_register(716, 300, slave=UNIT), "SP.HL = 300")
    support.check_equal(exception_code(client.write_register(717, 301, slave=UNIT), "SP above SP.HL"), 3, "exception 3")
    support.check_equal(registers(client, 717, 1, "SP after refusal"), [150], "SP unchanged after the refused write")


def check_rampsoak(client):
    """rampsoak-pid-rtu-ascii-linking.en.txt"""
    support.expect_reply(client.write_register(0, 250, slave=UNIT), "SV = 250")
    support.check_equal(registers(client, 0, 1, "SV"), [250], "SV at 0000H")
    # §4.6: at most 8 registers per request; read-only registers refuse writes (exception 2).
    support.check_equal(len(registers(client, 0, 8, "8 registers")), 8, "8 registers in one FC3")
    support.check_equal(exception_code(client.read_holding_registers(0, 9, slave=UNIT), "9 registers"), 3, "exception 3")
    support.check_equal(exception_code(client.write_register(7, 1, slave=UNIT), "program segment (read-only)"), 2, "exception 2")
    support.check_equal(exception_code(client.read_input_registers(0, 1, slave=UNIT), "FC4"), 1, "exception 1")


CHECKS = {"ac20": check_ac20, "tc10": check_tc10, "rampsoak": check_rampsoak}


def test():
    loopwire, device = sys.argv[1], sys.argv[2]
    with support.Processes() as processes:
        pty = os.path.join(processes.tmp, "tty")
        processes.start([loopwire, "simulate", "--link", "rtu:/unused?baud=19200&parity=none", "--pty", pty,
                         "--device", f"{device}@{UNIT}", "--duration", f"{support.PEER_LIFETIME_S}s", "-v"],
                        "simulate.log")
        support.wait_for_path(pty)
        # timeout=1: pymodbus 3.0.0rc1 truncates timeouts to whole seconds (PEERS.md).
        client = ModbusSerialClient(port=pty, framer=ModbusRtuFramer, baudrate=19200, parity="N",
                                    bytesize=8, stopbits=1, timeout=1, retries=0, retry_on_empty=False)
        if not client.connect():
            raise support.TestFailure(f"pymodbus cannot open {pty}")
        try:
            CHECKS[device](client)
        finally:
            client.close()


if __name__ == "__main__":
    support.main(test)
