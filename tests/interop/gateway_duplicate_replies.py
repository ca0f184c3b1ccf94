#!/usr/bin/python3
"""Replies a line delivers twice, late, never reach a Modbus TCP client as another request's.

Each line of the gateway is a paced relay (tests/support/paced_relay.py: 19200 baud, 10 bits a
character, up to 2 ms of lateness per write) between `loopwire simulate` serving a TC10 and the
gateway; the relay sends 15 % of the TC10's replies a second time, 150, 250 or 350 ms after the
first (drawn per copy). Eight pymodbus clients per line each write a value of their own, one
that changes every time, to a register of their own, read it back, and read the instrument id
(word 21, always 20): every answer must be the echo of the write, the value just written, or 20.
A late copy of one client's read has the shape of every other client's read of one register,
so a copy taken for the real reply shows as another client's value. Exception 0Bh (the gateway
refused a reply it could not trust) and client timeouts are counted apart: they are the price
of the faults, not errors. The test fails on any other answer.

One 19200-baud line carries at most ~85 of these requests a second, and far fewer when every
copy costs it a quiet late-reply window (the lines' timeout, 100 ms here: a one-register reply
comes within ~15 ms); the default is four lines behind one gateway (TC10s at units 3 to 6), each
with its own relay and eight clients, until 20,000 answers have been checked (about 150 s).

Usage: gateway_duplicate_replies.py LOOPWIRE [--answers N] [--lines N] [--max-seconds S]
                                    [--timeout-ms T] [--jitter-ms J]
"""

import argparse
import os
import re
import signal
import sys
import threading
import time

from pymodbus.client import ModbusTcpClient
from pymodbus.exceptions import ModbusException
from pymodbus.pdu import ExceptionResponse

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import interop_support as support  # noqa: E402  pylint: disable=wrong-import-position

RELAY = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "support", "paced_relay.py")
FIRST_UNIT = 3
CLIENTS_PER_LINE = 8
DUPLICATE_FRACTION = 0.15
DUPLICATE_DELAYS_MS = "150,250,350"
# TC10 words that take any value 1..9999 and act on nothing else (§5.3: the three alarm delays,
# the loop break alarm time, the compressor protection time, integral and derivative time, the
# load voltage): one per client.
OWN_REGISTERS = [672, 680, 688, 690, 699, 701, 702, 773]
INSTRUMENT_ID_REGISTER = 21   # §5.1 21A
INSTRUMENT_ID = 20            # the TC10's
# A client's values: 100 + (its index + 8 k) mod 9800, so they never equal another client's,
# nor the instrument id; a wrong value names the client whose it was.
VALUE_BASE = 100
VALUE_SPAN = 9800
# A request waits behind at most the other seven clients' requests on its line, each a timeout
# and a quiet late-reply window at worst: a client that waits longer than this has hit a hang.
CLIENT_TIMEOUT_S = 10
# Every background peer's own bound (interop_support.py): past the longest run and its start.
LIFETIME_S = 280


class Tally:
    """One client's counts; the lists hold the first wrong and unexpected answers (as text)."""

    def __init__(self):
        self.right = 0
        self.refused = 0       # exception 0Bh
        self.timeouts = 0      # no answer within CLIENT_TIMEOUT_S
        self.wrong = []        # another value than the client's own (or the instrument id)
        self.exceptions = []   # exception replies other than 0Bh: no value, so no wrong one
        self.unexpected = []   # any other error

    def answers(self):
        return self.right + self.refused + self.timeouts + len(self.wrong) + len(self.exceptions) + len(self.unexpected)


class Client:
    """One pymodbus client: write its own changing value, read it back, read the instrument id."""

    def __init__(self, port, unit, index, register, tally):
        self.port = port
        self.unit = unit
        self.index = index
        self.register = register
        self.tally = tally
        self.step = 0
        # What the register may hold: after a write that got no trustworthy answer, the device
        # may have taken it or not; both values are this client's own.
        self.possible = None
        self.connection = None

    def name(self):
        return f"unit {self.unit} register {self.register} (client {self.index})"

    def whose(self, value):
        if value == INSTRUMENT_ID:
            return "the instrument id"
        if VALUE_BASE <= value < VALUE_BASE + VALUE_SPAN:
            return f"client {(value - VALUE_BASE) % CLIENTS_PER_LINE}'s value"
        return "nobody's value (a poll's?)"

    def connect(self):
        self.connection = ModbusTcpClient("127.0.0.1", port=self.port, timeout=CLIENT_TIMEOUT_S, retries=0)
        if not self.connection.connect():
            raise support.TestFailure(f"{self.name()}: cannot connect to the gateway")

    def ask(self, call):
        """The response, or None after a timeout (then a new connection: a late answer on the
        old one must not be taken for the next request's)."""
        try:
            response = call()
        except ModbusException:
            response = None
        if response is not None and not (response.isError() and not isinstance(response, ExceptionResponse)):
            return response
        self.tally.timeouts += 1
        self.connection.close()
        self.connect()
        return None

    def failed(self, what, response):
        """True (counted) if the response is an exception. 0Bh is the gateway's refusal; another
        code is an answer that carries no value, so it is no wrong value either: listed and
        counted apart, not failed on (a TC10 exception 3 to a read comes about once in 40,000
        answers here, not yet explained)."""
        if not response.isError():
            return False
        if response.exception_code == 0x0B:
            self.tally.refused += 1
        else:
            self.tally.exceptions.append(f"{self.name()}: {what}: {response}")
        return True

    def check(self, value, allowed, what):
        if value in allowed:
            self.tally.right += 1
        else:
            self.tally.wrong.append(f"{self.name()}: {what}: got {value} ({self.whose(value)}), "
                                    f"expected {sorted(allowed)}")

    def cycle(self):
        value = VALUE_BASE + (self.index + CLIENTS_PER_LINE * self.step) % VALUE_SPAN
        self.step += 1
        response = self.ask(lambda: self.connection.write_register(self.register, value, slave=self.unit))
        if response is None or self.failed(f"write {value}", response):
            self.possible = {value} | (self.possible or set())
        else:
            echo = (response.address, response.value)
            if echo == (self.register, value):
                self.tally.right += 1
                self.possible = {value}
            else:
                self.tally.wrong.append(f"{self.name()}: write {value}: echo {echo}, not ({self.register}, {value})")
                self.possible = None
        response = self.ask(lambda: self.connection.read_holding_registers(self.register, 1, slave=self.unit))
        if response is not None and not self.failed("read back", response):
            if self.possible is None:
                self.tally.right += 1  # nothing known to compare with yet (a wrong echo was counted)
            else:
                self.check(response.registers[0], self.possible, "read back")
                if response.registers[0] in self.possible:
                    self.possible = {response.registers[0]}
        response = self.ask(lambda: self.connection.read_holding_registers(INSTRUMENT_ID_REGISTER, 1, slave=self.unit))
        if response is not None and not self.failed("read instrument id", response):
            self.check(response.registers[0], {INSTRUMENT_ID}, "instrument id")

    def run(self, stop):
        try:
            self.connect()
            while not stop.is_set():
                self.cycle()
        except support.TestFailure as failure:
            self.tally.unexpected.append(str(failure))
        finally:
            if self.connection is not None:
                self.connection.close()


def write_config(path, lines, timeout_ms):
    text = ""
    for line, (_, master_link) in enumerate(lines):
        text += f"""
[[lines]]
name = "relayed{line}"
link = "rtu:{master_link}?baud=19200&parity=none"
timeout = "{timeout_ms}ms"

[[lines.devices]]
name = "oven{line}"
device = "tc10@{FIRST_UNIT + line}"
poll = "1s"
parameters = ["set_point"]
"""
    text += """
[modbus_tcp]
listen = "127.0.0.1:0"
"""
    with open(path, "w", encoding="utf-8") as file:
        file.write(text)


def start_line(processes, line, jitter_ms):
    """The relay and the simulated TC10 of one line; returns their processes and the relay's
    (device, master) paths."""
    device_link = os.path.join(processes.tmp, f"ttyDevice{line}")
    master_link = os.path.join(processes.tmp, f"ttyMaster{line}")
    relay = processes.start(["/usr/bin/python3", RELAY, "--device-link", device_link, "--master-link", master_link,
                             "--baud", "19200", "--jitter-ms", str(jitter_ms), "--duplicate", str(DUPLICATE_FRACTION),
                             "--duplicate-delays-ms", DUPLICATE_DELAYS_MS, "--seed", str(line + 1), "--realtime",
                             "--lifetime", str(LIFETIME_S)], f"relay{line}.log")
    support.wait_for_log(processes, f"relay{line}.log", r"paced_relay: ready", 10)
    simulator = processes.start([LOOPWIRE, "simulate", "--link", f"rtu:{device_link}?baud=19200&parity=none",
                                 "--device", f"tc10@{FIRST_UNIT + line}", "--duration", f"{LIFETIME_S}s"],
                                f"simulate{line}.log")
    return relay, simulator, (device_link, master_link)


def line_statistics(log, line):
    found = re.findall(rf"line relayed{line} \([^)]*\): (\d+) sent, (\d+) answered, (\d+) timeout\(s\), "
                       r"(\d+) bad repl(?:y|ies), (\d+) garbled", log)
    if not found:
        return "no statistics in the gateway's log"
    sent, answered, timeouts, bad, garbled = found[-1]
    return f"{sent} sent, {answered} answered, {timeouts} timeouts, {bad} bad replies, {garbled} garbled frames"


def wait_for_answers(tallies, target, max_seconds):
    """Until the clients have `target` answers or max_seconds have passed; returns the seconds."""
    started = time.monotonic()
    while True:
        elapsed = time.monotonic() - started
        if sum(t.answers() for t in tallies) >= target or elapsed >= max_seconds:
            return elapsed
        time.sleep(0.2)  # polls the count; nothing here waits for an event


def test(options):
    with support.Processes() as processes:
        relays, simulators, links = [], [], []
        for line in range(options.lines):
            relay, simulator, pair = start_line(processes, line, options.jitter_ms)
            relays.append(relay)
            simulators.append(simulator)
            links.append(pair)
        config = os.path.join(processes.tmp, "plant.toml")
        write_config(config, links, options.timeout_ms)
        gateway = processes.start(["timeout", str(LIFETIME_S), LOOPWIRE, "gateway", "--config", config], "gateway.log")
        port = int(support.wait_for_log(processes, "gateway.log", r"listening on port (\d+)", 30).group(1))

        stop = threading.Event()
        tallies = {}
        threads = []
        for line in range(options.lines):
            for index, register in enumerate(OWN_REGISTERS[:CLIENTS_PER_LINE]):
                tally = tallies[(line, index)] = Tally()
                client = Client(port, FIRST_UNIT + line, index, register, tally)
                threads.append(threading.Thread(target=client.run, args=(stop,), daemon=True))
        for thread in threads:
            thread.start()
        seconds = wait_for_answers(tallies.values(), options.answers, options.max_seconds)
        stop.set()
        for thread in threads:
            thread.join(timeout=3 * CLIENT_TIMEOUT_S)
            if thread.is_alive():
                raise support.TestFailure("a client did not finish its last request")

        gateway.send_signal(signal.SIGTERM)  # its line statistics at exit
        gateway.wait(timeout=30)
        for simulator in simulators:  # before their relays, whose going they would take for a hang-up
            simulator.terminate()
            simulator.wait(timeout=10)
        for relay in relays:
            relay.send_signal(signal.SIGTERM)  # its counts at exit
            relay.wait(timeout=10)
        gateway_log = processes.log("gateway.log")

        everyone = list(tallies.values())
        answers = sum(t.answers() for t in everyone)
        wrong = [w for t in everyone for w in t.wrong]
        unexpected = [u for t in everyone for u in t.unexpected]
        exceptions = [e for t in everyone for e in t.exceptions]
        for line in range(options.lines):
            mine = [t for (l, _), t in tallies.items() if l == line]
            print(f"line {line} (unit {FIRST_UNIT + line}): {sum(t.answers() for t in mine)} answers, "
                  f"{sum(len(t.wrong) for t in mine)} wrong, {sum(t.refused for t in mine)} refused (0Bh), "
                  f"{sum(t.timeouts for t in mine)} timeouts")
            print(f"  {processes.log(f'relay{line}.log').splitlines()[-1]}")
            print(f"  gateway at exit: {line_statistics(gateway_log, line)}")
        print(f"clients: {answers} answers in {seconds:.0f} s: {sum(t.right for t in everyone)} right, "
              f"{len(wrong)} wrong, {sum(t.refused for t in everyone)} refused (0Bh), "
              f"{sum(t.timeouts for t in everyone)} timeouts, {len(exceptions)} other exception replies, "
              f"{len(unexpected)} other errors")
        for text in wrong[:20]:
            print(f"  wrong: {text}")
        for text in exceptions[:20]:
            print(f"  exception reply: {text}")
        support.check_equal(wrong[:5], [], "answers that were another request's")
        support.check_equal(unexpected[:5], [], "answers that were neither right, an exception reply nor a timeout")
        for line in range(options.lines):
            if not re.search(r"[1-9]\d* duplicated", processes.log(f"relay{line}.log")):
                raise support.TestFailure(f"the relay of line {line} duplicated no reply")
        if answers < options.answers:
            raise support.TestFailure(f"only {answers} answers in {options.max_seconds} s, not {options.answers}: "
                                      "too few to show that wrong answers do not happen")


def parse_arguments(argv):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n", maxsplit=1)[0])
    parser.add_argument("loopwire")
    parser.add_argument("--answers", type=int, default=20000, help="answers to check in all (default 20000)")
    parser.add_argument("--lines", type=int, default=4, choices=range(1, 9), help="relayed lines (default 4)")
    parser.add_argument("--max-seconds", type=float, default=200, help="stops there if --answers is not reached (fails)")
    parser.add_argument("--timeout-ms", type=int, default=100,
                        help="the gateway lines' reply timeout, and so their late-reply window (default 100)")
    parser.add_argument("--jitter-ms", type=float, default=2.0, help="the relays' jitter (default 2)")
    return parser.parse_args(argv)


if __name__ == "__main__":
    OPTIONS = parse_arguments(sys.argv[1:])
    LOOPWIRE = OPTIONS.loopwire
    support.main(lambda: test(OPTIONS))
