#!/usr/bin/python3
"""A serial line between two pseudo-terminals that keeps the timing of a real one.

Pseudo-terminals deliver a frame the instant it is written, however slow the line they stand
for; a device on a real 19200-baud line gets one character every 10 bits (1/1920 s), and the
host that reads it wakes up a little late now and then (a USB adapter's latency timer, a busy
scheduler). This relay stands for that line: it makes two pseudo-terminal pairs of its own and
links their far ends at the paths given, one for the device (a slave such as `loopwire
simulate`), one for the master (such as `loopwire gateway`), and passes bytes between them:

  * paced: a byte arrives one character time after the one before it in its frame (10 bits a
    character unless --bits says otherwise), never sooner; frames in one direction keep 3.5
    characters of silence between them;
  * with jitter: each write of the bytes that are due comes up to --jitter-ms later than they
    are due (uniform), as a host that wakes late. Jitter never reorders bytes and never makes
    the silence between two bytes of one frame longer than --jitter-ms (or one character time,
    if that is longer): a longer gap would end the frame on any receiver, and that is a broken
    line, not a late host. The silence the relay really left is measured and reported, since
    its own wake-ups can be late too on a loaded machine;
  * optionally duplicated: --duplicate FRACTION of the device's frames (its replies: bytes
    ended by 3.5 characters of silence from the device side) are sent again to the master,
    paced too: the copy starts a delay after the reply's last byte is due at the master, the
    delay drawn from --duplicate-delays-ms (a repeater or a second path that sends a frame
    twice, late). A copy never cuts into a frame: it waits for the wire, as any frame does.

Frames are delimited by silence on the side they come from, with the character time of
--baud: the peers write a frame at once, so that silence is always there between frames.
A byte written to a side that nobody reads is lost once the pseudo-terminal's buffer is full,
as on a wire with no listener.

It runs until SIGTERM or SIGINT (or --lifetime seconds), then prints its counts on stdout:
  paced_relay: master->device N frames (B bytes), device->master N frames (B bytes),
    D duplicated (delays MS ms: COUNT, ...), longest silence inside a frame X ms (limit L ms),
    G gaps longer than the limit (late wake-ups of this process), K bytes lost (nobody reading)
A run on a loaded machine shows G above 0: its silences were longer than the jitter asked for,
and frames a receiver split there are the machine's doing, not the receiver's.

Usage: paced_relay.py --device-link PATH --master-link PATH [--baud 19200] [--bits 10]
                      [--jitter-ms 2] [--duplicate 0.15] [--duplicate-delays-ms 150,250,350]
                      [--seed N] [--realtime] [--lifetime SECONDS]
"""

import argparse
import collections
import errno
import os
import random
import select
import signal
import sys
import time
import tty

# Silence that ends a frame and must separate two frames, in characters (Modbus over serial
# line V1.02, 2.5.1.1). At most 3.5 characters at 19200 baud: above it the spec fixes 1.75 ms.
FRAME_SILENCE_CHARACTERS = 3.5
FIXED_FRAME_SILENCE_ABOVE_19200_S = 0.00175
# A gap inside a frame this much longer than the relay planned is counted as a late wake-up
# (Python's select() itself overshoots by some tens of microseconds).
LATE_WAKE_TOLERANCE_S = 0.0003
# Low among real-time priorities: above every ordinary process, below the kernel's own threads.
REALTIME_PRIORITY = 10


class Pty:
    """One pseudo-terminal pair: the relay holds the master side; the slave side's path is
    linked at `link` for a peer to open. The relay keeps the slave side open too, so that the
    master side does not fail with EIO while the peer has it closed (before it opens it, or
    between two runs)."""

    def __init__(self, link):
        self.fd, self._slave = os.openpty()
        tty.setraw(self._slave)  # no echo, no line editing, until the peer sets its own modes
        os.set_blocking(self.fd, False)
        self.link = link
        if os.path.lexists(link):
            os.unlink(link)
        os.symlink(os.ttyname(self._slave), link)

    def close(self):
        try:
            os.unlink(self.link)
        except OSError:
            pass
        os.close(self.fd)
        os.close(self._slave)


class SourceFrames:
    """Delimits the frames one side sends: bytes up to 3.5 characters of silence."""

    def __init__(self, silence_s):
        self.silence_s = silence_s
        self.open_frame = None  # id of the frame still being received
        self.last_read = 0.0
        self.frames = 0
        self.bytes = 0

    def received(self, count, now, new_frame_id):
        """Returns the id of the frame these bytes belong to."""
        if self.open_frame is None:
            self.open_frame = new_frame_id()
        self.last_read = now
        self.bytes += count
        return self.open_frame

    def closes_at(self):
        return None if self.open_frame is None else self.last_read + self.silence_s

    def close_if_silent(self, now):
        """The id of the frame that has just ended, or None."""
        if self.open_frame is None or now < self.last_read + self.silence_s:
            return None
        ended, self.open_frame = self.open_frame, None
        self.frames += 1
        return ended


class Wire:
    """One direction of the line: bytes queued with the time each is due at the far end,
    written in bursts at planned (jittered) times."""

    def __init__(self, out_fd, character_s, silence_s, jitter_s, draw):
        self.out_fd = out_fd
        self.character_s = character_s
        self.silence_s = silence_s
        self.jitter_s = jitter_s
        self.gap_limit_s = max(jitter_s, character_s)
        self.draw = draw
        self.pending = collections.deque()  # [due, frame id, byte]
        self.last_due = None                 # of the last byte queued
        self.last_queued_frame = None
        self.last_write = None               # when the last burst was written
        self.last_written_frame = None
        self.planned = None                  # when the next burst is to be written
        self.longest_gap_s = 0.0
        self.late_gaps = 0
        self.lost_bytes = 0

    def queue(self, data, frame_id, now):
        """Queues bytes of a frame that reached the relay at `now`."""
        for byte in data:
            if self.last_due is None:
                start = now
            elif frame_id == self.last_queued_frame:
                start = max(now, self.last_due)  # back to back with the byte before it
            else:
                start = max(now, self.last_due + self.silence_s)
            self.last_due = start + self.character_s  # its stop bit has arrived
            self.last_queued_frame = frame_id
            self.pending.append((self.last_due, frame_id, byte))

    def busy(self):
        return bool(self.pending)

    def next_write_at(self):
        if not self.pending:
            return None
        if self.planned is None:
            self.planned = self._plan()
        return self.planned

    def _plan(self):
        due, frame_id, _ = self.pending[0]
        if frame_id == self.last_written_frame and self.last_write is not None:
            # Inside a frame: late, but the silence since the last burst stays within the limit.
            room = self.jitter_s - (due - self.last_write)
            return due + self.draw.uniform(0.0, max(0.0, room))
        planned = due + self.draw.uniform(0.0, self.jitter_s)
        if self.last_write is not None:
            # The previous frame may have been written late: the silence between the two stays.
            planned = max(planned, self.last_write + self.silence_s + self.character_s)
        return planned

    def write_due(self, now):
        """Writes the bytes of one frame that are due by now, once the planned time has come."""
        if self.planned is None or now < self.planned:
            return
        frame_id = self.pending[0][1]
        burst = bytearray()
        while self.pending and self.pending[0][1] == frame_id and self.pending[0][0] <= now:
            burst.append(self.pending.popleft()[2])
        if not burst:  # woken for the planned time by a clock that disagrees by a hair
            burst.append(self.pending.popleft()[2])
        if frame_id == self.last_written_frame and self.last_write is not None:
            gap = now - self.last_write
            self.longest_gap_s = max(self.longest_gap_s, gap)
            if gap > self.gap_limit_s + LATE_WAKE_TOLERANCE_S:
                self.late_gaps += 1
        self._write(bytes(burst))
        self.last_write = now
        self.last_written_frame = frame_id
        self.planned = None

    def _write(self, data):
        try:
            written = os.write(self.out_fd, data)
        except BlockingIOError:
            written = 0
        except OSError as error:
            if error.errno != errno.EIO:
                raise
            written = 0
        self.lost_bytes += len(data) - written


class Relay:
    def __init__(self, args):
        self.character_s = args.bits / args.baud
        self.silence_s = (FIXED_FRAME_SILENCE_ABOVE_19200_S if args.baud > 19200
                          else FRAME_SILENCE_CHARACTERS * self.character_s)
        self.jitter_s = args.jitter_ms / 1000
        self.duplicate = args.duplicate
        self.delays_s = [ms / 1000 for ms in args.duplicate_delays_ms]
        self.draw = random.Random(args.seed)
        self.device = Pty(args.device_link)
        self.master = Pty(args.master_link)
        self.to_device = Wire(self.device.fd, self.character_s, self.silence_s, self.jitter_s, self.draw)
        self.to_master = Wire(self.master.fd, self.character_s, self.silence_s, self.jitter_s, self.draw)
        self.from_master = SourceFrames(self.silence_s)
        self.from_device = SourceFrames(self.silence_s)
        self.copies = []  # (due, bytes) of duplicated replies, in the order they are due
        self.reply_bytes = {}  # frame id -> bytes of the device frame being received
        self.duplicated = collections.Counter()  # delay in ms -> copies
        self.frame_ids = iter(range(1, sys.maxsize))
        self.stopping = False

    def new_frame_id(self):
        return next(self.frame_ids)

    def run(self, deadline):
        while not self.stopping and time.monotonic() < deadline:
            now = time.monotonic()
            wake = [deadline, now + 0.05]
            for at in (self.to_device.next_write_at(), self.to_master.next_write_at(),
                       self.from_master.closes_at(), self.from_device.closes_at()):
                if at is not None:
                    wake.append(at)
            if self.copies and self.from_device.open_frame is None:  # else it waits for the frame's end
                wake.append(self.copies[0][0])
            try:
                readable, _, _ = select.select([self.master.fd, self.device.fd], [], [], max(0.0, min(wake) - now))
            except InterruptedError:
                continue
            now = time.monotonic()
            if self.master.fd in readable:
                self.receive(self.master.fd, self.from_master, self.to_device, now, keep=False)
            if self.device.fd in readable:
                self.receive(self.device.fd, self.from_device, self.to_master, now, keep=True)
            self.from_master.close_if_silent(now)
            ended = self.from_device.close_if_silent(now)
            if ended is not None:
                # Its bytes are the last queued for the master: no copy is queued while a reply
                # is open (queue_due_copies), so last_due is when its last byte arrives there.
                self.maybe_duplicate(self.reply_bytes.pop(ended), self.to_master.last_due)
            self.queue_due_copies(now)
            self.to_device.write_due(time.monotonic())
            self.to_master.write_due(time.monotonic())

    def receive(self, fd, source, wire, now, keep):
        try:
            data = os.read(fd, 4096)
        except (BlockingIOError, InterruptedError):
            return
        except OSError as error:
            if error.errno == errno.EIO:
                return
            raise
        if not data:
            return
        frame_id = source.received(len(data), now, self.new_frame_id)
        wire.queue(data, frame_id, now)
        if keep:
            self.reply_bytes[frame_id] = self.reply_bytes.get(frame_id, b"") + data

    def maybe_duplicate(self, reply, delivered_at):
        if self.duplicate <= 0 or self.draw.random() >= self.duplicate:
            return
        delay = self.draw.choice(self.delays_s)
        self.copies.append((delivered_at + delay, reply))
        self.copies.sort(key=lambda copy: copy[0])
        self.duplicated[round(delay * 1000)] += 1

    def queue_due_copies(self, now):
        # A copy never cuts into a reply still coming from the device: it waits until that
        # reply has ended, then follows it after the frames' silence (Wire.queue).
        while self.copies and self.copies[0][0] <= now and self.from_device.open_frame is None:
            _, reply = self.copies.pop(0)
            self.to_master.queue(reply, self.new_frame_id(), now)

    def report(self):
        limit_ms = 1000 * max(self.jitter_s, self.character_s)
        longest_ms = 1000 * max(self.to_device.longest_gap_s, self.to_master.longest_gap_s)
        delays = ", ".join(f"{ms} ms: {count}" for ms, count in sorted(self.duplicated.items())) or "none"
        lost = self.to_device.lost_bytes + self.to_master.lost_bytes
        print(f"paced_relay: master->device {self.from_master.frames} frames ({self.from_master.bytes} bytes), "
              f"device->master {self.from_device.frames} frames ({self.from_device.bytes} bytes), "
              f"{sum(self.duplicated.values())} duplicated (delays {delays}), "
              f"longest silence inside a frame {longest_ms:.2f} ms (limit {limit_ms:.2f} ms), "
              f"{self.to_device.late_gaps + self.to_master.late_gaps} gaps longer than the limit "
              f"(late wake-ups of this process), {lost} bytes lost (nobody reading)", flush=True)

    def close(self):
        self.device.close()
        self.master.close()


def delays_ms(text):
    try:
        delays = [int(part) for part in text.split(",")]
    except ValueError as error:
        raise argparse.ArgumentTypeError(f"'{text}' is not a comma-separated list of milliseconds") from error
    if not delays or any(delay < 0 for delay in delays):
        raise argparse.ArgumentTypeError(f"'{text}': give one or more delays of 0 ms or more")
    return delays


def fraction(text):
    value = float(text)
    if not 0.0 <= value <= 1.0:
        raise argparse.ArgumentTypeError(f"{text} is not a fraction between 0 and 1")
    return value


def parse_arguments(argv):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n", maxsplit=1)[0])
    parser.add_argument("--device-link", required=True, help="path to link to the device's pseudo-terminal")
    parser.add_argument("--master-link", required=True, help="path to link to the master's pseudo-terminal")
    parser.add_argument("--baud", type=int, default=19200, help="line speed (default 19200)")
    parser.add_argument("--bits", type=int, default=10,
                        help="bits a character: start + data + parity + stop (default 10, 8N1)")
    parser.add_argument("--jitter-ms", type=float, default=2.0,
                        help="how late a write may come, in ms, uniform (default 2)")
    parser.add_argument("--duplicate", type=fraction, default=0.0,
                        help="fraction of the device's frames sent again to the master (default 0)")
    parser.add_argument("--duplicate-delays-ms", type=delays_ms, default=[150, 250, 350],
                        help="a copy comes one of these delays after the reply, drawn at random (default 150,250,350)")
    parser.add_argument("--seed", type=int, default=1, help="seed of the jitter and duplicate draws (default 1)")
    parser.add_argument("--realtime", action="store_true",
                        help="run at real-time priority (SCHED_FIFO) if allowed: the relay stands for a UART, "
                             "which a busy host does not delay; the ready line says whether it was granted")
    parser.add_argument("--lifetime", type=float, default=600.0,
                        help="stops after this many seconds even without a signal (default 600)")
    args = parser.parse_args(argv)
    if args.baud <= 0 or args.bits <= 0 or args.jitter_ms < 0 or args.lifetime <= 0:
        parser.error("--baud, --bits and --lifetime must be positive, --jitter-ms not negative")
    return args


def scheduling(realtime):
    """Asks for real-time priority if wanted; says what the relay runs at."""
    if not realtime:
        return "normal priority"
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(REALTIME_PRIORITY))
    except (OSError, AttributeError) as error:
        return f"normal priority (real-time refused: {error})"
    return f"real-time priority {REALTIME_PRIORITY}"


def main(argv):
    args = parse_arguments(argv)
    relay = Relay(args)
    priority = scheduling(args.realtime)

    def stop(_signal, _frame):
        relay.stopping = True

    signal.signal(signal.SIGTERM, stop)
    signal.signal(signal.SIGINT, stop)
    print(f"paced_relay: ready: device at {args.device_link}, master at {args.master_link}, {args.baud} baud, "
          f"{args.bits} bits a character, jitter up to {args.jitter_ms:g} ms, "
          f"{args.duplicate:g} of replies duplicated, {priority}", flush=True)
    try:
        relay.run(time.monotonic() + args.lifetime)
    finally:
        relay.report()
        relay.close()


if __name__ == "__main__":
    main(sys.argv[1:])
