#!/usr/bin/python3
"""A pymodbus serial slave with known contents, for loopwire's master side to talk to.

Usage: pymodbus_serial_server.py SERIAL_PATH UNIT rtu|ascii

Serves one unit on SERIAL_PATH with RTU or ASCII framing, as 19200 8N1 whatever loopwire's
link says (pseudo-terminals keep 8N1 anyway: see pymodbus_rtu_client.py), and stays silent for
every other unit (single=False). Each table holds TABLE_SIZE entries from
address 0, so reading past them draws exception 2 (illegal data address). The expected
contents are importable, so the test compares against the same definition.
"""

import sys

TABLE_SIZE = 200


def holding_preset(address):
    return (1000 + 3 * address) & 0xFFFF


def input_preset(address):
    return 50000 - address


def coil_preset(address):
    return address % 3 == 0


def discrete_preset(address):
    return address % 2 == 1


def serve(path, unit, framing):
    from pymodbus.datastore import ModbusSequentialDataBlock, ModbusServerContext, ModbusSlaveContext
    from pymodbus.framer.ascii_framer import ModbusAsciiFramer
    from pymodbus.framer.rtu_framer import ModbusRtuFramer
    from pymodbus.server import StartSerialServer

    addresses = range(TABLE_SIZE)
    # zero_mode=True: block address 0 is wire address 0 (otherwise pymodbus shifts by one).
    slave = ModbusSlaveContext(
        hr=ModbusSequentialDataBlock(0, [holding_preset(a) for a in addresses]),
        ir=ModbusSequentialDataBlock(0, [input_preset(a) for a in addresses]),
        co=ModbusSequentialDataBlock(0, [coil_preset(a) for a in addresses]),
        di=ModbusSequentialDataBlock(0, [discrete_preset(a) for a in addresses]),
        zero_mode=True)
    context = ModbusServerContext(slaves={unit: slave}, single=False)
    # framer= always: without it pymodbus's serial server speaks ASCII (PEERS.md).
    framer = {"rtu": ModbusRtuFramer, "ascii": ModbusAsciiFramer}[framing]
    print(f"pymodbus {framing} server: unit {unit} on {path}", flush=True)
    StartSerialServer(context=context, framer=framer, port=path, baudrate=19200, bytesize=8, parity="N", stopbits=1)


if __name__ == "__main__":
    serve(sys.argv[1], int(sys.argv[2]), sys.argv[3])
