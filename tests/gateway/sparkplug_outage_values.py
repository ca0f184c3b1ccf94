#!/usr/bin/env python3
"""Whether every value of an outage came as historical, once: the changes the gateway's
[history] (SQLite) recorded for one parameter between the last live value the observer saw before
the outage and the birth after it, against the historical values the observer received
(sparkplug_check.py series). Prints the figures; exit status 0 when they are the same.

Values sampled before the first historical one that are neither received live nor as historical
were published live (QoS 0, as Sparkplug has DDATA) while the broker was going away, before the
node saw its connection end: lost in flight, not kept. They are counted apart, and at most
MAX_IN_FLIGHT of them (0.5 s of 100 ms polls) are let through; any other value missing fails.

With UNTIL_MS, the changes up to that time only (a gateway stopped during the outage: what the
next run recorded before its birth was never kept to forward).

usage: sparkplug_outage_values.py HISTORY_DB DEVICE PARAMETER OUTAGE_LINE [UNTIL_MS] < SERIES"""
import sqlite3
import sys

MAX_IN_FLIGHT = 5


def main():
    database, device, parameter, outage_line = sys.argv[1], sys.argv[2], sys.argv[3], int(sys.argv[4])
    until = int(sys.argv[5]) if len(sys.argv) > 5 else None
    live_before, birth_after, received = None, None, []
    for text in sys.stdin:
        line, kind, ts, value, flag = text.split()
        line, ts = int(line), int(ts)
        value = None if value == "null" else round(float(value), 6)
        if line < outage_line and flag == "L":
            live_before = ts
        elif line > outage_line and kind == "DBIRTH" and birth_after is None:
            birth_after = ts
        elif line > outage_line and flag == "H":
            received.append((ts, value))
    if live_before is None or birth_after is None:
        print(f"no live value before line {outage_line} or no birth after it")
        return 1
    db = sqlite3.connect(f"file:{database}?mode=ro", uri=True)
    rows = db.execute("SELECT s.t, s.value FROM samples s JOIN series r ON r.id = s.series_id "
                      "WHERE r.device = ? AND r.parameter = ? ORDER BY s.t", (device, parameter)).fetchall()
    # The changes: a heartbeat repeats the last value, and is no value of its own.
    changes, last = [], object()
    for t, value in rows:
        value = None if value is None else round(value, 6)
        if value != last:
            changes.append((t, value))
        last = value
    expected = [(t, v) for t, v in changes if live_before < t < birth_after and (until is None or t <= until)]
    first_historical = received[0][0] if received else None
    missing_all = [c for c in expected if c not in received]
    in_flight = [c for c in missing_all if first_historical is not None and c[0] < first_historical]
    missing = [c for c in missing_all if c not in in_flight]
    extra = [c for c in received if c not in expected]
    print(f"recorded changes in the outage={len(expected)} historical received={len(received)} "
          f"missing={len(missing)} lost_in_flight={len(in_flight)} not recorded={len(extra)}")
    for what, items in (("missing", missing), ("lost in flight", in_flight), ("not recorded", extra)):
        for t, v in items[:5]:
            print(f"  {what}: {t} {v}")
    ok = not missing and len(in_flight) <= MAX_IN_FLIGHT and not extra and received == sorted(received)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
