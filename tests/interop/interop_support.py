"""Shared plumbing for the Python interop tests (run with /usr/bin/python3, which sees pymodbus).

Every background process a test starts is bounded three ways, so a crashed or killed test
never leaves a peer running on the machine:
  * the test's `Processes` context manager kills it on exit, also on an exception;
  * it gets PR_SET_PDEATHSIG, so the kernel sends it SIGTERM if the test process dies
    (CTest's timeout kills the test with SIGKILL, which runs no Python cleanup);
  * it has a lifetime of its own (`timeout N` or `loopwire simulate --duration`).
"""

import contextlib
import ctypes
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time

# Upper bound on the life of any background peer: well above a test's few seconds, even in a
# sanitized build where every loopwire run is several times slower (the typed-values test takes
# 46 s under AddressSanitizer), and below CTest's 240 s per-test timeout.
PEER_LIFETIME_S = 200

_PR_SET_PDEATHSIG = 1
_libc = ctypes.CDLL(None, use_errno=True)


def _die_with_parent():
    _libc.prctl(_PR_SET_PDEATHSIG, signal.SIGTERM)


class TestFailure(Exception):
    """A check did not hold; main() prints it and exits 1."""


def check_equal(actual, expected, what):
    if actual != expected:
        raise TestFailure(f"{what}: expected {expected!r}, got {actual!r}")
    shown = repr(actual)
    print(f"ok: {what} = {shown if len(shown) < 120 else shown[:100] + ' ...'}")


class Processes(contextlib.AbstractContextManager):
    """Background processes of one test, and the temporary directory they share."""

    def __init__(self):
        self.tmp = tempfile.mkdtemp(prefix="loopwire-interop.")
        self._running = []

    def start(self, argv, log_name):
        """Starts argv with stdout and stderr in TMP/log_name; returns the Popen."""
        log = open(os.path.join(self.tmp, log_name), "wb")  # pylint: disable=consider-using-with
        process = subprocess.Popen(argv, stdin=subprocess.DEVNULL, stdout=log, stderr=subprocess.STDOUT,
                                   preexec_fn=_die_with_parent)
        log.close()
        self._running.append((process, log_name))
        return process

    def log(self, log_name):
        with open(os.path.join(self.tmp, log_name), "r", encoding="utf-8", errors="replace") as file:
            return file.read()

    def __exit__(self, exc_type, exc, traceback):
        for process, _ in self._running:
            if process.poll() is None:
                process.terminate()
        for process, log_name in self._running:
            try:
                process.wait(timeout=5)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait()
            if exc_type is not None:
                # The logs are the evidence when a test fails: show them before deleting them.
                print(f"--- {log_name} (exit {process.returncode}) ---\n{self.log(log_name)}", file=sys.stderr)
        shutil.rmtree(self.tmp, ignore_errors=True)
        return False

    def socat_pair(self, name_a="ttyA", name_b="ttyB"):
        """A connected pseudo-terminal pair, as two paths; waits until both links exist."""
        a = os.path.join(self.tmp, name_a)
        b = os.path.join(self.tmp, name_b)
        self.start(["timeout", str(PEER_LIFETIME_S), "socat",
                    f"pty,raw,echo=0,link={a}", f"pty,raw,echo=0,link={b}"], "socat.log")
        wait_for_path(a)
        wait_for_path(b)
        return a, b


def wait_for_path(path, timeout_s=5.0):
    deadline = time.monotonic() + timeout_s
    while not os.path.exists(path):
        if time.monotonic() > deadline:
            raise TestFailure(f"{path} did not appear within {timeout_s} s")
        time.sleep(0.01)


def wait_for_log(processes, log_name, pattern, timeout_s=5.0):
    """Waits until the log matches pattern; returns the match."""
    deadline = time.monotonic() + timeout_s
    while True:
        match = re.search(pattern, processes.log(log_name))
        if match:
            return match
        if time.monotonic() > deadline:
            raise TestFailure(f"{log_name} did not show /{pattern}/ within {timeout_s} s:\n{processes.log(log_name)}")
        time.sleep(0.01)


def run_loopwire(loopwire, args, expect_exit=0, timeout_s=10):
    """Runs a loopwire command to completion; checks its exit status; returns parsed --json output
    (or None when it exited non-zero)."""
    started = time.monotonic()
    done = subprocess.run([loopwire, *args], capture_output=True, text=True, timeout=timeout_s, check=False)
    took = time.monotonic() - started
    if done.returncode != expect_exit:
        raise TestFailure(f"loopwire {' '.join(args)}: exit {done.returncode}, expected {expect_exit}\n"
                          f"stdout: {done.stdout}\nstderr: {done.stderr}")
    print(f"ok: loopwire {' '.join(args)} -> exit {done.returncode} in {took:.2f} s")
    if done.returncode == 0 and "--json" in args:
        return json.loads(done.stdout)
    return None


def main(test):
    """Runs test() and turns its outcome into an exit status for CTest."""
    try:
        test()
    except TestFailure as failure:
        print(f"FAIL: {failure}", file=sys.stderr)
        sys.exit(1)
    print("PASS")


def expect_reply(response, what):
    """A pymodbus response that must be a normal reply."""
    if response.isError():
        raise TestFailure(f"{what}: pymodbus got an error instead of a reply: {response}")
    return response


def check_register_bank(client, unit, base):
    """Drives one unit of `loopwire simulate` (a plain register bank) through a pymodbus client:
    every write function, read back with the matching read function, and the two read-only
    tables still zero. `base` spreads the addresses so tests do not all use the same ones."""
    values = [base, 0xFFFF, 0, 0x8000, 12345]
    expect_reply(client.write_registers(base, values, slave=unit), "FC16")
    expect_reply(client.write_register(base + 2, 777, slave=unit), "FC6")
    values[2] = 777
    check_equal(expect_reply(client.read_holding_registers(base, 5, slave=unit), "FC3").registers, values,
                f"holding {base}..{base + 4}")
    pattern = [True, True, False, True, False, False, False, True, True, False, True]
    expect_reply(client.write_coils(base, pattern, slave=unit), "FC15")
    expect_reply(client.write_coil(base + 4, True, slave=unit), "FC5")
    pattern[4] = True
    check_equal(expect_reply(client.read_coils(base, len(pattern), slave=unit), "FC1").bits[:len(pattern)], pattern,
                f"coils {base}..{base + len(pattern) - 1}")
    check_equal(expect_reply(client.read_input_registers(base, 5, slave=unit), "FC4").registers, [0] * 5,
                f"input {base}..{base + 4}")
    check_equal(expect_reply(client.read_discrete_inputs(base, 11, slave=unit), "FC2").bits[:11], [False] * 11,
                f"discrete {base}..{base + 10}")


def check_silent(client, unit):
    """A request for a unit nobody serves gets no reply at all."""
    started = time.monotonic()
    response = client.read_holding_registers(0, 1, slave=unit)
    if not response.isError():
        raise TestFailure(f"unit {unit} is not served but answered: {response}")
    print(f"ok: unit {unit} got no reply after {time.monotonic() - started:.2f} s ({response})")
