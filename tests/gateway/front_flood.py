#!/usr/bin/python3
"""Clients that try to exhaust the gateway's Modbus TCP front, and an honest one.

  front_flood.py idle PORT COUNT HOLD_FILE
      opens COUNT connections that never send a byte, prints "opened COUNT", and keeps them
      until HOLD_FILE is removed (120 s at most);
  front_flood.py storm PORT COUNT UNIT ADDRESS
      COUNT times: connect, send a read of one holding register, close at once (no reply read);
      prints how many were sent;
  front_flood.py hold-read PORT UNIT ADDRESS HOLD_FILE
      one connection: reads one holding register and prints "value N", keeps the connection
      until HOLD_FILE is removed (120 s at most), then reads again on it and prints
      "value N on the same connection"; a connection the gateway closed meanwhile fails;
  front_flood.py write PORT UNIT ADDRESS VALUE / read PORT UNIT ADDRESS
      the honest client (pymodbus): writes one holding register, or reads one and prints
      "value N"; an exception reply prints "exception N" and exits 1.
"""

import os
import resource
import socket
import struct
import sys
import time

from pymodbus.client import ModbusTcpClient
from pymodbus.pdu import ExceptionResponse


def fail(message):
    print(f"FAIL: {message}", flush=True)
    sys.exit(1)


def connect(port):
    return socket.create_connection(("127.0.0.1", port), timeout=10)


def hold_idle(port, count, hold_file):
    # This process needs a descriptor per connection: its own soft limit goes up to its hard one.
    needed = count + 64
    _, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    if hard != resource.RLIM_INFINITY and hard < needed:
        fail(f"this test needs {needed} descriptors; the hard limit is {hard}")
    resource.setrlimit(resource.RLIMIT_NOFILE, (needed, hard))
    sockets = []
    for i in range(count):
        try:
            sockets.append(connect(port))
        except OSError as error:
            fail(f"connection {i} failed: {error}")
    print(f"opened {len(sockets)}", flush=True)
    deadline = time.monotonic() + 120
    while os.path.exists(hold_file) and time.monotonic() < deadline:
        time.sleep(0.05)  # polling for the file the test removes when it is done
    for held in sockets:
        held.close()


def read_request(transaction, unit, address):
    pdu = struct.pack(">BHH", 3, address, 1)
    return struct.pack(">HHHB", transaction, 0, len(pdu) + 1, unit) + pdu


def read_on(client, transaction, unit, address):
    client.sendall(read_request(transaction, unit, address))
    reply = b""
    while len(reply) < 9:
        chunk = client.recv(256)
        if not chunk:
            fail("the gateway closed the connection")
        reply += chunk
    if reply[7] != 3 or len(reply) < 11:
        fail(f"not a read reply: {reply.hex(' ')}")
    return struct.unpack(">H", reply[9:11])[0]


def hold_read(port, unit, address, hold_file):
    with connect(port) as client:
        print(f"value {read_on(client, 1, unit, address)}", flush=True)
        deadline = time.monotonic() + 120
        while os.path.exists(hold_file) and time.monotonic() < deadline:
            time.sleep(0.05)  # polling for the file the test removes when it is done
        print(f"value {read_on(client, 2, unit, address)} on the same connection", flush=True)


def storm(port, count, unit, address):
    sent = 0
    for i in range(count):
        try:
            with connect(port) as client:
                client.sendall(read_request(i & 0xFFFF, unit, address))
                sent += 1
        except OSError:
            pass  # a connection the gateway closed for a newer one: part of the storm
    print(f"storm sent {sent} of {count}", flush=True)


def honest_client(port):
    client = ModbusTcpClient("127.0.0.1", port=port, timeout=5, retries=0, retry_on_empty=False)
    if not client.connect():
        fail(f"pymodbus cannot connect to the gateway on port {port}")
    return client


def answer_of(response, what):
    if isinstance(response, ExceptionResponse):
        print(f"exception {response.exception_code}", flush=True)
        sys.exit(1)
    if response.isError():
        fail(f"{what}: {response}")
    return response


def main():
    mode, port = sys.argv[1], int(sys.argv[2])
    if mode == "idle":
        hold_idle(port, int(sys.argv[3]), sys.argv[4])
    elif mode == "storm":
        storm(port, int(sys.argv[3]), int(sys.argv[4]), int(sys.argv[5]))
    elif mode == "hold-read":
        hold_read(port, int(sys.argv[3]), int(sys.argv[4]), sys.argv[5])
    elif mode == "write":
        client = honest_client(port)
        answer_of(client.write_register(int(sys.argv[4]), int(sys.argv[5]), slave=int(sys.argv[3])), "write")
        print("written", flush=True)
        client.close()
    elif mode == "read":
        client = honest_client(port)
        reply = answer_of(client.read_holding_registers(int(sys.argv[4]), 1, slave=int(sys.argv[3])), "read")
        print(f"value {reply.registers[0]}", flush=True)
        client.close()
    else:
        fail(f"unknown mode {mode}")


if __name__ == "__main__":
    main()
