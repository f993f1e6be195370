#!/usr/bin/env python3
"""The viewer under a slowloris (issue 46's probe, re-run): N connections trickle their request
heads a byte per second for D seconds, reconnecting whenever the server closes one, while a
normal client asks for /api/info every 0.25 s. Prints the normal requests' latencies and how many
were answered.

    results/faults/slowloris.py PORT [--sockets 50] [--seconds 20]

(`evogs view RUN --port PORT` must be listening on 127.0.0.1.)"""
import argparse
import socket
import statistics
import threading
import time

p = argparse.ArgumentParser()
p.add_argument("port", type=int)
p.add_argument("--sockets", type=int, default=50)
p.add_argument("--seconds", type=float, default=20.0)
a = p.parse_args()

HEAD = b"GET /api/info HTTP/1.1\r\nHost: 127.0.0.1\r\nX-Slow: " + b"a" * 4096
stop = time.monotonic() + a.seconds
reconnects = [0]
lock = threading.Lock()


def trickler():
    while time.monotonic() < stop:
        try:
            s = socket.create_connection(("127.0.0.1", a.port), timeout=5)
        except OSError:
            time.sleep(0.1)
            continue
        with lock:
            reconnects[0] += 1
        try:
            for b in HEAD:
                if time.monotonic() >= stop:
                    break
                s.sendall(bytes([b]))
                time.sleep(1.0)
        except OSError:
            pass  # closed by the server: reconnect
        finally:
            s.close()


threads = [threading.Thread(target=trickler, daemon=True) for _ in range(a.sockets)]
for t in threads:
    t.start()
time.sleep(1.0)  # let every slow connection open first

latencies, failures = [], 0
while time.monotonic() < stop:
    t0 = time.monotonic()
    try:
        s = socket.create_connection(("127.0.0.1", a.port), timeout=10)
        s.sendall(b"GET /api/info HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n")
        data = b""
        while True:
            chunk = s.recv(65536)
            if not chunk:
                break
            data += chunk
        s.close()
        if data.startswith(b"HTTP/1.1 200"):
            latencies.append(time.monotonic() - t0)
        else:
            failures += 1
    except OSError:
        failures += 1
    time.sleep(0.25)

for t in threads:
    t.join()
print(
    f"slowloris: {a.sockets} trickling connections for {a.seconds:.0f} s "
    f"({reconnects[0]} connections opened); normal requests: {len(latencies)} answered 200, "
    f"{failures} not; latency median {1000 * statistics.median(latencies):.1f} ms, "
    f"max {1000 * max(latencies):.1f} ms"
    if latencies
    else f"slowloris: no normal request answered ({failures} failed)"
)
