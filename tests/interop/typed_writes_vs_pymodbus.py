#!/usr/bin/python3
"""Typed writes (`write --type ... --word-order ...`) into a pymodbus RTU slave, decoded by
pymodbus's own BinaryPayloadDecoder: an implementation of the byte and word orders independent
of loopwire's.

Usage: typed_writes_vs_pymodbus.py LOOPWIRE

For each of the four byte orders Modbus tools name (ABCD, CDAB, BADC, DCBA) loopwire writes
float32 and float64 values; the slave's registers, read back as plain words, must decode with
pymodbus to exactly the numbers written. Then scaled integers, reference addresses (40001 is
holding register 1), strings against pymodbus's own string registers, and the refusals a user
meets: a fraction for an integer type, a value out of range, a word order given twice, text that
is not ASCII or too long.
"""

import os
import subprocess
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import interop_support as support  # noqa: E402  pylint: disable=wrong-import-position

UNIT = 7

# pymodbus's byteorder swaps the bytes within each register, its wordorder the registers.
ORDERS = {
    "ABCD": ("big", "big"),
    "CDAB": ("big", "little"),
    "BADC": ("little", "big"),
    "DCBA": ("little", "little"),
}


def serve(path):
    from pymodbus.datastore import ModbusSequentialDataBlock, ModbusServerContext, ModbusSlaveContext
    from pymodbus.framer.rtu_framer import ModbusRtuFramer
    from pymodbus.server import StartSerialServer

    slave = ModbusSlaveContext(hr=ModbusSequentialDataBlock(0, [0] * 1100), zero_mode=True)
    context = ModbusServerContext(slaves={UNIT: slave}, single=False)
    print(f"pymodbus typed-writes slave: unit {UNIT} on {path}", flush=True)
    StartSerialServer(context=context, framer=ModbusRtuFramer, port=path, baudrate=19200, bytesize=8, parity="N", stopbits=1)


def decoder(words, order):
    from pymodbus.constants import Endian
    from pymodbus.payload import BinaryPayloadDecoder

    byteorder, wordorder = ORDERS[order]
    endian = {"big": Endian.Big, "little": Endian.Little}
    return BinaryPayloadDecoder.fromRegisters(words, byteorder=endian[byteorder], wordorder=endian[wordorder])


def float32_as_meant(value):
    """The float32 nearest to `value`, as the shortest decimal that reads back as it (what
    loopwire writes and shows): struct rounds through a real float32."""
    import struct

    single = struct.unpack(">f", struct.pack(">f", value))[0]
    for digits in range(1, 18):
        text = f"{single:.{digits}g}"
        if struct.unpack(">f", struct.pack(">f", float(text)))[0] == single:
            return float(text)
    return single


def pymodbus_string_registers(text):
    """The registers pymodbus's own BinaryPayloadBuilder makes of `text` (high byte first)."""
    from pymodbus.payload import BinaryPayloadBuilder

    builder = BinaryPayloadBuilder()
    builder.add_string(text)
    return builder.to_registers()


def check_strings(loopwire, master, words_at):
    """Strings both ways: loopwire's registers decoded by pymodbus, pymodbus's registers read by
    loopwire; an odd length padded with NUL; the low-byte-first order is pymodbus's registers
    with their bytes swapped."""
    from pymodbus.payload import BinaryPayloadDecoder

    text = "Modbus 1.1b3!"  # odd: the last register is "!" and NUL
    support.run_loopwire(loopwire, ["write", *master, "holding", "900", text, "--type", "string"])
    words = words_at(900, 7)
    support.check_equal(words, pymodbus_string_registers(text), "string: the registers pymodbus makes of the same text")
    decoded = BinaryPayloadDecoder.fromRegisters(words).decode_string(14)
    support.check_equal(decoded, text.encode("ascii") + b"\0", "string decoded by pymodbus, NUL-padded")

    theirs = pymodbus_string_registers("TC10 oven")
    support.run_loopwire(loopwire, ["write", *master, "holding", "920", *map(str, theirs)])
    read = support.run_loopwire(loopwire, ["read", *master, "holding", "920", str(len(theirs)), "--type", "string", "--json"])
    support.check_equal(read["values"], ["TC10 oven"], "pymodbus's string registers read by loopwire up to the NUL")

    swapped = [((word & 0xFF) << 8) | (word >> 8) for word in pymodbus_string_registers("Hi there")]
    support.run_loopwire(loopwire, ["write", *master, "holding", "940", "Hi there", "--type", "string", "--byte-swap"])
    support.check_equal(words_at(940, 4), swapped, "string --byte-swap: low byte first")
    for order in ("BADC", "DCBA"):
        read = support.run_loopwire(loopwire, ["read", *master, "holding", "940", "4", "--type", "string", "--word-order", order, "--json"])
        support.check_equal(read["values"], ["Hi there"], f"string read back with --word-order {order}")


def test():
    loopwire = sys.argv[1]
    with support.Processes() as processes:
        slave_side, master_side = processes.socat_pair()
        processes.start(["timeout", str(support.PEER_LIFETIME_S), "/usr/bin/python3", os.path.abspath(__file__),
                         "--serve", slave_side], "pymodbus-server.log")
        support.wait_for_log(processes, "pymodbus-server.log", "typed-writes slave")
        master = ["--link", f"rtu:{master_side}?baud=19200&parity=none", "--unit", str(UNIT), "--timeout", "500ms"]

        deadline = time.monotonic() + 10
        while subprocess.run([loopwire, "read", *master, "holding", "0"], capture_output=True, timeout=10, check=False).returncode:
            if time.monotonic() > deadline:
                raise support.TestFailure("the pymodbus server never answered")
            time.sleep(0.1)

        def words_at(address, count):
            return support.run_loopwire(loopwire, ["read", *master, "holding", str(address), str(count), "--json"])["values"]

        floats = [12.5, -3.25, 0.1, 273.15, 1e10]
        doubles = [3.141592653589793, -1e-300, 6.02214076e23]
        for index, order in enumerate(ORDERS):
            at = 100 * index
            written = support.run_loopwire(loopwire, ["write", *master, "holding", str(at), *map(str, floats),
                                                      "--type", "float32", "--word-order", order, "--json"])
            support.check_equal(written["values"], floats, f"float32 {order}: what loopwire says it wrote")
            words = words_at(at, 2 * len(floats))
            support.check_equal(written["registers"], words, f"float32 {order}: the registers the slave holds")
            got = [float32_as_meant(decoder(words[i:i + 2], order).decode_32bit_float()) for i in range(0, len(words), 2)]
            support.check_equal(got, floats, f"float32 {order} decoded by pymodbus")

            at += 50
            support.run_loopwire(loopwire, ["write", *master, "holding", str(at), *map(str, doubles),
                                            "--type", "float64", "--word-order", order, "--json"])
            words = words_at(at, 4 * len(doubles))
            got = [decoder(words[i:i + 4], order).decode_64bit_float() for i in range(0, len(words), 4)]
            support.check_equal(got, doubles, f"float64 {order} decoded by pymodbus")

            # Read back by loopwire with the same order: the round trip.
            read = support.run_loopwire(loopwire, ["read", *master, "holding", str(at), str(len(doubles)), "--type", "float64",
                                                   "--word-order", order, "--json"])
            support.check_equal(read["values"], doubles, f"float64 {order} read back by loopwire")

        # big and little are ABCD and CDAB; --byte-swap turns them into BADC and DCBA.
        for order, flags, name in (("big", [], "ABCD"), ("little", [], "CDAB"), ("big", ["--byte-swap"], "BADC"),
                                   ("little", ["--byte-swap"], "DCBA")):
            support.run_loopwire(loopwire, ["write", *master, "holding", "500", "-7.75", "--type", "float32",
                                            "--word-order", order, *flags])
            got = decoder(words_at(500, 2), name).decode_32bit_float()
            support.check_equal(got, -7.75, f"--word-order {order} {' '.join(flags)} is {name}")

        # Scaled integers: 123.4 with --scale 0.1 is the int32 1234; -2 with --scale 0.5 is -4.
        support.run_loopwire(loopwire, ["write", *master, "holding", "600", "123.4", "-2", "--type", "int32", "--scale", "0.1"])
        words = words_at(600, 4)
        support.check_equal([decoder(words[0:2], "ABCD").decode_32bit_int(), decoder(words[2:4], "ABCD").decode_32bit_int()],
                            [1234, -20], "scaled int32 decoded by pymodbus")
        support.run_loopwire(loopwire, ["write", *master, "holding", "610", "4000000000", "--type", "uint32", "--word-order", "CDAB"])
        support.check_equal(decoder(words_at(610, 2), "CDAB").decode_32bit_uint(), 4000000000, "uint32 CDAB decoded by pymodbus")

        # A reference address names its table and counts from 1: 40701 is wire address 700.
        support.run_loopwire(loopwire, ["write", *master, "40701", "1234"])
        support.check_equal(words_at(700, 1), [1234], "write 40701 lands at wire address 700")
        support.run_loopwire(loopwire, ["write", *master, "holding", "40702", "-2", "--type", "int16", "--base", "1"])
        support.check_equal(words_at(701, 1), [0xFFFE], "holding 40702 --base 1 lands at wire address 701")
        shown = support.run_loopwire(loopwire, ["read", *master, "40701", "2", "--json"])
        support.check_equal((shown["table"], shown["address"], shown["values"]), ("holding", 40701, [1234, 0xFFFE]),
                            "read 40701 2 shows reference addresses")

        check_strings(loopwire, master, words_at)

        # Refusals say what was wrong and write nothing.
        before = words_at(800, 2)
        for args, expected in (
            (["holding", "800", "12.5", "--type", "int16"], "not a whole number for int16"),
            (["holding", "800", "70000", "--type", "uint16"], "does not fit uint16: give 0..65535"),
            (["holding", "800", "12.34", "--type", "int16", "--scale", "0.1"], "give 12.3 or 12.4"),
            (["holding", "800", "1", "--type", "float32", "--word-order", "BADC", "--byte-swap"], "drop --byte-swap"),
            (["holding", "800", "abc", "--type", "float32"], "'abc' is not a number for float32"),
            (["holding", "800", "1", "--type", "float32", "--word-order", "ACBD"], "ABCD (big)"),
            (["input", "800", "1"], "input are read-only"),
            (["coils", "800", "1", "--type", "int16"], "coils are single bits"),
            (["holding", "65535", "1.5", "--type", "float32"], "only 1 remain"),
            (["holding", "800", "Grüße", "--type", "string"], "is not printable ASCII text"),
            (["holding", "800", "x" * 247, "--type", "string"], "one write carries at most 123 (246 characters)"),
        ):
            done = subprocess.run([loopwire, "write", *master, *args], capture_output=True, text=True, timeout=10, check=False)
            support.check_equal((done.returncode, expected in done.stderr), (2, True),
                                f"write {' '.join(args)} refused: {done.stderr.strip()}")
        support.check_equal(words_at(800, 2), before, "the refused writes changed nothing")


if __name__ == "__main__":
    if len(sys.argv) == 3 and sys.argv[1] == "--serve":
        serve(sys.argv[2])
    else:
        support.main(test)
