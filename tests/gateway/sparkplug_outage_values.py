#!/usr/bin/env python3
"""Whether every value of an outage came as historical, once: the changes the gateway's
[history] (SQLite) recorded for one parameter between the last live value the observer saw before
the outage and the birth after it, against the historical values the observer received
(sparkplug_check.py series). Prints the figures; exit status 0 when they are the same.

usage: sparkplug_outage_values.py HISTORY_DB DEVICE PARAMETER OUTAGE_LINE < SERIES"""
import sqlite3
import sys


def main():
    database, device, parameter, outage_line = sys.argv[1], sys.argv[2], sys.argv[3], int(sys.argv[4])
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
    expected = [(t, v) for t, v in changes if live_before < t < birth_after]
    missing = [c for c in expected if c not in received]
    extra = [c for c in received if c not in expected]
    print(f"recorded changes in the outage={len(expected)} historical received={len(received)} "
          f"missing={len(missing)} not recorded={len(extra)}")
    for what, items in (("missing", missing), ("not recorded", extra)):
        for t, v in items[:5]:
            print(f"  {what}: {t} {v}")
    return 0 if not missing and not extra and received == sorted(received) else 1


if __name__ == "__main__":
    sys.exit(main())
