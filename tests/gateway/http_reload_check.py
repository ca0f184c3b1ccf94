#!/usr/bin/python3
"""One HTTP client on one keep-alive connection asks a running gateway back to back while the
gateway is reloaded again and again (SIGHUP after a change that reopens it, [http] listen left
alone): every request must be answered 200 on that same connection.

usage: http_reload_check.py PORT GATEWAY_PID CONFIG LOG RELOADS
Each reload renames the device (oven-a <-> oven-b), so an answer naming the new name shows the
reloaded gateway answering. Prints what it saw; exits 1 on any failure.
"""
import http.client
import os
import signal
import sys
import time

port, pid, config, log, reloads = int(sys.argv[1]), int(sys.argv[2]), sys.argv[3], sys.argv[4], int(sys.argv[5])
connection = http.client.HTTPConnection("127.0.0.1", port, timeout=30)
answered = 0
failures = []
sockets = set()


def ask():
    """One GET /api/devices on the kept connection; its body, or None after recording why."""
    global answered
    try:
        connection.request("GET", "/api/devices")
        response = connection.getresponse()
        body = response.read().decode()
    except Exception as error:  # the connection closed under the client, or a timeout
        failures.append(f"after {answered} answers: {error!r}")
        connection.close()
        return None
    sockets.add(connection.sock.getsockname()[1])  # the client side port: a new one for each new connection
    if response.status != 200:
        failures.append(f"after {answered} answers: status {response.status}")
        return None
    answered += 1
    return body


def reloads_logged():
    with open(log, encoding="utf-8", errors="replace") as text:
        return sum(1 for line in text if "reloaded" in line and "configuration" in line)


for reload in range(1, reloads + 1):
    name, new_name = ("oven-a", "oven-b") if reload % 2 else ("oven-b", "oven-a")
    with open(config, encoding="utf-8") as text:
        before = text.read()
    with open(config, "w", encoding="utf-8") as text:
        text.write(before.replace(f'name = "{name}"', f'name = "{new_name}"'))
    for _ in range(10):
        ask()
    os.kill(pid, signal.SIGHUP)
    deadline = time.monotonic() + 30
    # Asking all along (the reload happens among these requests), until the reloaded gateway
    # has answered with the new name and 30 requests have gone since the signal.
    since_signal = 0
    while True:
        body = ask()
        since_signal += 1
        if body is not None and f'"{new_name}"' in body and reloads_logged() >= reload and since_signal >= 30:
            break
        if time.monotonic() > deadline:
            failures.append(f"reload {reload}: the gateway never answered as reloaded within 30 s")
            break
        if len(failures) > 5:
            break

print(f"{answered} requests answered across {reloads_logged()} reloads on {len(sockets)} connection(s)")
for failure in failures[:5]:
    print("FAIL", failure)
if failures or len(sockets) != 1:
    sys.exit(1)
