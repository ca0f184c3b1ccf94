#!/usr/bin/python3
"""One pymodbus client of the gateway's Modbus TCP front from a chosen loopback source address.

Usage: allow_list_client.py SOURCE PORT read|write [VALUE]
Prints what happened: "value N", "written", "exception N", or "no connection" (the front
closed it at accept, or a read got nothing back)."""

import sys

from pymodbus.client import ModbusTcpClient

UNIT = 3
SET_POINT = 717  # TC10 set point (TC10 manual, §5.3)


def main():
    source, port, action = sys.argv[1], int(sys.argv[2]), sys.argv[3]
    client = ModbusTcpClient("127.0.0.1", port=port, timeout=3, retries=0, source_address=(source, 0))
    if not client.connect():
        print("no connection")
        return
    try:
        if action == "write":
            response = client.write_register(SET_POINT, int(sys.argv[4]), slave=UNIT)
        else:
            response = client.read_holding_registers(SET_POINT, 1, slave=UNIT)
    except Exception as error:  # pylint: disable=broad-except  # a closed connection, as pymodbus says it
        print(f"no connection ({type(error).__name__})")
        return
    finally:
        client.close()
    if response.isError() and not hasattr(response, "exception_code"):
        print(f"no connection ({response})")  # pymodbus 3.0 returns an I/O error as its response
    elif response.isError():
        print(f"exception {response.exception_code}")
    elif action == "write":
        print("written")
    else:
        print(f"value {response.registers[0]}")


if __name__ == "__main__":
    main()
