#!/usr/bin/env python3
"""Command round trip and status latency through gateway and core, on loopback.

Starts `safestate run --no-opcua` on a free port (or, with --port, uses one already running:
bench/run.py --ws) and measures, as a Python `websockets` client sees it:
  - round trip: WebSocket `command` -> gateway -> shared memory -> core cycle -> reply;
  - status latency: a `sim` input change -> the first `status` message that shows it
    (includes waiting for the next core cycle and the gateway's 50 Hz status push).
Prints p50/p99/max in milliseconds. A measurement, not a test: nothing is asserted. The
round-trip goal is measured by the C++ client bench/ws_rtt.cpp, whose own cost is smaller.
"""
import argparse
import asyncio
import json
import os
import random
import signal
import socket
import statistics
import subprocess
import sys
import tempfile
import time
import urllib.request

import websockets


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def pct(xs, p):
    xs = sorted(xs)
    return xs[min(len(xs) - 1, int(round(p / 100.0 * (len(xs) - 1))))]


def summary(name, xs):
    return (f"{name:<34} n={len(xs):5d}  p50 {pct(xs, 50):7.3f} ms  p99 {pct(xs, 99):7.3f} ms"
            f"  max {max(xs):7.3f} ms  mean {statistics.fmean(xs):7.3f} ms")


async def measure(port, n_cmd, n_status):
    async with websockets.connect(f"ws://127.0.0.1:{port}/ws", max_size=2**20) as ws:
        await ws.send(json.dumps({"type": "hello", "role": "pendant", "client": "bench"}))
        async def next_of(kind, pred=lambda m: True):
            while True:
                m = json.loads(await ws.recv())
                if m.get("type") == kind and pred(m):
                    return m
        await next_of("welcome")
        rtt = []
        for seq in range(1, n_cmd + 1):
            # Paced at random (4-6 ms apart): the gateway takes at most 250 records per
            # second from one client, and a random phase against the 1 ms cycle measures
            # what a client sees, not one lucky phase.
            await asyncio.sleep(random.uniform(0.004, 0.006))
            t0 = time.perf_counter()
            # `set_mode` is always answered (MODE_BY_SELECTOR_ONLY) and changes nothing.
            await ws.send(json.dumps({"type": "command", "seq": seq, "cmd": "set_mode", "mode": "T1"}))
            r = await next_of("reply", lambda m, s=seq: m.get("seq") == s)
            if r["result"] != "MODE_BY_SELECTOR_ONLY":
                raise SystemExit(f"reply {r}: not answered by the core, the measurement would be wrong")
            rtt.append((time.perf_counter() - t0) * 1000.0)
        lat = []
        mode = "AUTO"
        for seq in range(2 * 10**6, 2 * 10**6 + n_status):
            mode = "T1" if mode == "AUTO" else "AUTO"
            t0 = time.perf_counter()
            await ws.send(json.dumps({"type": "sim", "seq": seq, "set": {"mode": mode}}))
            await next_of("status", lambda m, md=mode: m.get("mode") == md)
            lat.append((time.perf_counter() - t0) * 1000.0)
        return rtt, lat


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--bin", default=os.environ.get("SAFESTATE_BIN", "build/bin/safestate"))
    ap.add_argument("--commands", type=int, default=2000)
    ap.add_argument("--status", type=int, default=300)
    ap.add_argument("--json", help="also write the figures (ms) to this file")
    ap.add_argument("--port", type=int, help="measure a `safestate run` already listening on this port")
    a = ap.parse_args()
    if a.port:
        rtt, lat = asyncio.run(measure(a.port, a.commands, a.status))
        report(a, rtt, lat)
        return 0
    port = free_port()
    with tempfile.TemporaryDirectory() as d:
        # Without the OPC UA adapter: its start-up (node) would run during the measurement.
        proc = subprocess.Popen([a.bin, "run", "--no-opcua", "--port", str(port), "--db", os.path.join(d, "ev.db")],
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        try:
            for _ in range(200):
                try:
                    urllib.request.urlopen(f"http://127.0.0.1:{port}/api/status", timeout=1).read()
                    break
                except OSError:
                    time.sleep(0.05)
            rtt, lat = asyncio.run(measure(port, a.commands, a.status))
        finally:
            proc.send_signal(signal.SIGINT)
            proc.wait(timeout=15)
    report(a, rtt, lat)
    return 0


def report(a, rtt, lat):
    print(summary("command round trip (WS->core->WS)", rtt))
    print(summary("input change -> status message", lat))
    if a.json:
        fig = lambda xs: {"n": len(xs), "p50": pct(xs, 50), "p99": pct(xs, 99), "max": max(xs)}
        with open(a.json, "w") as f:
            json.dump({"round_trip_ms": fig(rtt), "status_ms": fig(lat)}, f)


if __name__ == "__main__":
    sys.exit(main())
