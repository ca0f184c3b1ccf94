#!/usr/bin/python3
"""Real Modbus TCP clients through `loopwire gateway`, at the same time as its own polling.

Five lines behind one gateway: simulated TC10 (unit 3) and ramp/soak (unit 5) on a
pseudo-terminal RTU line, a plain register bank behind a Modbus TCP device that takes one
connection (unit 7), one behind an RTU-over-TCP device server (unit 8), and ramp/soak
controllers on an ASCII line (unit 6) and a Linking line (unit 11). pymodbus, libmodbus
and mbpoll read and write through the gateway concurrently; a unit no line leads to gets
exception 0Ah, a configured unit that stays silent 0Bh; a unit-0 request is broadcast on the
lines and answered by nobody; a client that pipelines without reading and one that stalls
halfway through a header do not delay the others.

Usage: gateway_peers.py LOOPWIRE LIBMODBUS_TCP_CLIENT
"""

import os
import re
import socket
import struct
import subprocess
import sys
import threading
import time

from pymodbus.client import ModbusTcpClient
from pymodbus.pdu import ExceptionResponse

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import interop_support as support  # noqa: E402  pylint: disable=wrong-import-position

# A read that waits behind at most one request of each other client on a 19200-baud line takes
# a few tens of milliseconds; this bound catches a client stuck behind another's whole queue.
LATENCY_BOUND_S = 0.5


def start_tcp_simulator(processes, link, unit, log):
    processes.start([LOOPWIRE, "simulate", "--link", link, "--unit", str(unit),
                     "--duration", f"{support.PEER_LIFETIME_S}s"], log)
    return int(support.wait_for_log(processes, log, r"listening on port (\d+)").group(1))


def write_config(path, pty, tcp_port, rtu_tcp_port, ascii_pty, linking_pty):
    with open(path, "w", encoding="utf-8") as file:
        file.write(f"""
[[lines]]
name = "furnace"
link = "rtu:{pty}?baud=19200&parity=none"
timeout = "300ms"

[[lines.devices]]
name = "oven"
device = "tc10@3"
poll = "500ms"

[[lines.devices]]
name = "kiln"
device = "rampsoak@5"
poll = "500ms"

[[lines.devices]]
name = "silent"
device = "tc10@4"
poll = "2s"

[[lines]]
name = "tcp-device"
link = "tcp://127.0.0.1:{tcp_port}"

[[lines.devices]]
name = "bank7"
device = "tc10@7"
parameters = ["measured_value"]
identify = false  # a plain register bank stands for a TC10 here: taken as it is, not identified

[[lines]]
name = "device-server"
link = "rtu+tcp://127.0.0.1:{rtu_tcp_port}"

[[lines.devices]]
name = "bank8"
device = "tc10@8"
parameters = ["measured_value"]
identify = false  # a plain register bank stands for a TC10 here: taken as it is, not identified

[[lines]]
name = "ascii-line"
link = "ascii:{ascii_pty}?baud=9600&parity=even&data=7"

[[lines.devices]]
name = "ramp-ascii"
device = "rampsoak@6"

[[lines]]
name = "linking-line"
link = "linking:{linking_pty}?baud=38400&parity=odd"

[[lines.devices]]
name = "ramp-linking"
device = "rampsoak@11"

[modbus_tcp]
listen = "127.0.0.1:0"
""")


def client(port):
    tcp = ModbusTcpClient("127.0.0.1", port=port, timeout=3, retries=0, retry_on_empty=False)
    if not tcp.connect():
        raise support.TestFailure(f"pymodbus cannot connect to the gateway on port {port}")
    return tcp


def read_one(tcp, unit, address, what):
    return support.expect_reply(tcp.read_holding_registers(address, 1, slave=unit), what).registers[0]


def write_and_read_back(tcp, unit, address, value, what):
    support.expect_reply(tcp.write_register(address, value, slave=unit), f"{what}: write")
    support.check_equal(read_one(tcp, unit, address, f"{what}: read"), value, what)


def exception_code(response, what):
    if not isinstance(response, ExceptionResponse):
        raise support.TestFailure(f"{what}: expected an exception reply, got {response}")
    return response.exception_code


def mbap(transaction, unit, pdu):
    return struct.pack(">HHHB", transaction, 0, len(pdu) + 1, unit) + pdu


def check_each_back_end(port):
    tcp = client(port)
    try:
        write_and_read_back(tcp, 3, 717, 123, "TC10 SP through the RTU line")      # TC10 manual, SP at 717
        write_and_read_back(tcp, 5, 0, 321, "ramp/soak SV through the RTU line")    # ramp/soak SV at 0000h
        write_and_read_back(tcp, 7, 100, 4242, "register 100 behind the TCP device")
        write_and_read_back(tcp, 8, 200, 4343, "register 200 behind the device server")
        support.check_equal(exception_code(tcp.read_holding_registers(0, 1, slave=9), "unit 9"), 0x0A,
                            "exception for a unit no line leads to (gateway path unavailable)")
        support.check_equal(exception_code(tcp.read_holding_registers(0, 1, slave=4), "unit 4"), 0x0B,
                            "exception for a silent unit (gateway target failed to respond)")
    finally:
        tcp.close()


def check_ascii_and_linking_lines(port):
    """An ASCII line carries every function as it is; the ramp/soak controller's Linking frames
    carry one register read or write (manual, chapter 6): FC3 of one register and FC6 go
    through, anything else gets exception 1 from the gateway."""
    tcp = client(port)
    try:
        write_and_read_back(tcp, 6, 0, 250, "ramp/soak SV through the ASCII line")
        write_and_read_back(tcp, 11, 0, 260, "ramp/soak SV through the Linking line")
        support.check_equal(exception_code(tcp.read_holding_registers(0, 2, slave=11), "two registers over Linking"), 1,
                            "exception for a request Linking frames cannot carry (illegal function)")
    finally:
        tcp.close()


def check_other_peers(port):
    out = subprocess.run([LIBMODBUS_CLIENT, "127.0.0.1", str(port), "7", "read", "holding", "100", "1"],
                         capture_output=True, text=True, timeout=10, check=False)
    support.check_equal((out.returncode, out.stdout.strip()), (0, "4242"), "libmodbus reads unit 7 through the gateway")
    out = subprocess.run(["timeout", "10", "mbpoll", "-m", "tcp", "-p", str(port), "-a", "5", "-0", "-1", "-r", "0", "-c", "1",
                          "127.0.0.1"], capture_output=True, text=True, check=False)
    if out.returncode != 0 or not re.search(r"^\[0\]:\s+321\b", out.stdout, re.MULTILINE):
        raise support.TestFailure(f"mbpoll through the gateway: exit {out.returncode}\n{out.stdout}{out.stderr}")
    print("ok: mbpoll reads unit 5 through the gateway")


def check_clients_at_once(port):
    """Four clients on three lines at once, while the gateway polls: every answer right."""
    failures = []

    def pymodbus_loop(unit, address, value):
        tcp = client(port)
        try:
            for i in range(30):
                got = read_one(tcp, unit, address, f"unit {unit} read {i}")
                if got != value:
                    failures.append(f"unit {unit} read {i}: {got} instead of {value}")
        except support.TestFailure as failure:
            failures.append(str(failure))
        finally:
            tcp.close()

    def libmodbus_loop():
        for i in range(15):
            out = subprocess.run([LIBMODBUS_CLIENT, "127.0.0.1", str(port), "3", "read", "holding", "717", "1"],
                                 capture_output=True, text=True, timeout=10, check=False)
            if out.returncode != 0 or out.stdout.strip() != "123":
                failures.append(f"libmodbus read {i}: exit {out.returncode}, {out.stdout.strip()!r} {out.stderr.strip()}")

    threads = [threading.Thread(target=pymodbus_loop, args=args) for args in ((3, 717, 123), (5, 0, 321), (7, 100, 4242))]
    threads.append(threading.Thread(target=libmodbus_loop))
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(60)
    if failures:
        raise support.TestFailure("clients at once:\n  " + "\n  ".join(failures))
    print("ok: pymodbus x3 and libmodbus at once, 105 reads, all right")


def check_broadcast(port):
    """Unit 0: executed by the devices on the line that take broadcasts (the TC10 does; the
    ramp/soak manual describes none), answered by nobody (serial line spec 2.1)."""
    with socket.create_connection(("127.0.0.1", port), timeout=3) as raw:
        raw.sendall(mbap(0x4242, 0, bytes([0x06, 0x02, 0xCD, 0x00, 77])))  # TC10 SP (717) := 77
        raw.settimeout(0.7)
        try:
            reply = raw.recv(64)
        except socket.timeout:
            reply = None
        if reply:
            raise support.TestFailure(f"a broadcast was answered: {reply.hex(' ')}")
    tcp = client(port)
    try:
        deadline = time.monotonic() + 3
        while read_one(tcp, 3, 717, "SP after the broadcast") != 77:
            if time.monotonic() > deadline:
                raise support.TestFailure("the broadcast write did not reach the TC10")
            time.sleep(0.05)
        print("ok: a unit-0 write reached unit 3 and nobody answered it")
        write_and_read_back(tcp, 3, 717, 123, "TC10 SP restored")
    finally:
        tcp.close()


def check_hostile_clients(port):
    """A client pipelining reads it never collects and one stalled halfway through an MBAP header:
    another client's reads keep their latency."""
    hog = socket.create_connection(("127.0.0.1", port), timeout=3)
    hog.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    stalled = socket.create_connection(("127.0.0.1", port), timeout=3)
    try:
        stalled.sendall(b"\x00\x01\x00")
        hog.setblocking(False)
        batch = b"".join(mbap(i, 3, bytes([0x03, 0x02, 0xCD, 0x00, 0x01])) for i in range(200))
        try:
            hog.send(batch)
        except BlockingIOError:
            pass
        tcp = client(port)
        try:
            worst = 0.0
            for i in range(20):
                started = time.monotonic()
                read_one(tcp, 5, 0, f"read {i} beside the hostile clients")
                worst = max(worst, time.monotonic() - started)
            if worst > LATENCY_BOUND_S:
                raise support.TestFailure(f"a read beside the hostile clients took {worst:.3f} s (bound {LATENCY_BOUND_S} s)")
            print(f"ok: 20 reads beside a pipelining and a stalled client, the slowest {worst * 1000:.0f} ms")
        finally:
            tcp.close()
    finally:
        hog.close()
        stalled.close()


def test():
    with support.Processes() as processes:
        pty = os.path.join(processes.tmp, "ttyG")
        processes.start([LOOPWIRE, "simulate", "--link", "rtu:/unused?baud=19200&parity=none", "--pty", pty,
                         "--device", "tc10@3", "--device", "rampsoak@5", "--duration", f"{support.PEER_LIFETIME_S}s"],
                        "line.log")
        support.wait_for_path(pty)
        tcp_port = start_tcp_simulator(processes, "tcp://127.0.0.1:0", 7, "tcp-device.log")
        rtu_tcp_port = start_tcp_simulator(processes, "rtu+tcp://127.0.0.1:0", 8, "device-server.log")
        ascii_pty = os.path.join(processes.tmp, "ttyAscii")
        processes.start([LOOPWIRE, "simulate", "--link", "ascii:/unused?baud=9600&parity=even&data=7", "--pty", ascii_pty,
                         "--device", "rampsoak@6", "--duration", f"{support.PEER_LIFETIME_S}s"], "ascii-line.log")
        linking_pty = os.path.join(processes.tmp, "ttyLinking")
        processes.start([LOOPWIRE, "simulate", "--link", "linking:/unused?baud=38400&parity=odd", "--pty", linking_pty,
                         "--device", "rampsoak@11", "--duration", f"{support.PEER_LIFETIME_S}s"], "linking-line.log")
        support.wait_for_path(ascii_pty)
        support.wait_for_path(linking_pty)
        config = os.path.join(processes.tmp, "plant.toml")
        write_config(config, pty, tcp_port, rtu_tcp_port, ascii_pty, linking_pty)
        processes.start(["timeout", str(support.PEER_LIFETIME_S), LOOPWIRE, "gateway", "--config", config], "gateway.log")
        port = int(support.wait_for_log(processes, "gateway.log", r"listening on port (\d+)").group(1))

        check_each_back_end(port)
        check_ascii_and_linking_lines(port)
        check_other_peers(port)
        check_clients_at_once(port)
        check_broadcast(port)
        check_hostile_clients(port)
        support.wait_for_log(processes, "gateway.log", r"device oven \(tc10@3\) answers")
        support.wait_for_log(processes, "gateway.log", r"device silent \(tc10@4\) does not answer")


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit("usage: gateway_peers.py LOOPWIRE LIBMODBUS_TCP_CLIENT")
    LOOPWIRE, LIBMODBUS_CLIENT = sys.argv[1], sys.argv[2]
    support.main(test)
