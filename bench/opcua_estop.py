#!/usr/bin/env python3
"""Issue 14's OPC UA figure: from a sim E-stop press to the notification of an OPC UA
subscription on `EmergencyStop` (OPC 40010-1), as an independent client (asyncua) sees it.

Starts `safestate run` with its OPC UA adapter on the SIMULATED cell (free ports), subscribes as
tests/integration/test_opcua.py does (requested publishing interval 20 ms, sampling interval 0;
the server revises the publishing interval, and the figure is what a client gets with it), then
presses the E-stop (both channels, the gateway's `sim` message, as the HMI's panel sends it)
OPCUA_PRESSES times (default 20) from the start on, each at a random phase (0-100 ms after the
last reset), and times each press from just before the `sim` message is sent to the
notification's arrival; on OPCUA_CELLS fresh cells (default 5). Twice: on an otherwise idle
host, and with one busy loop per core (bounded, killed at the end), as a full `make test` loads
this machine.

Writes
  - build/bench/opcua.json: the raw figures (`--render` rewrites the document from it);
  - in docs/performance.md, the goal row "A subscription sees EmergencyStop within 200 ms ..."
    (after the command round-trip row) and the section "## OPC UA: E-stop press to a
    subscription's notification (ms)" (replaced in place, or added before "## Footprint").
A measurement, not a test: nothing fails when the goal is missed; the document says so. The
functional test (opcua_server) asserts only a margin above these figures (test_opcua.py
ESTOP_NOTIFY_MARGIN_S). Needs the test venv (asyncua) and `make opcua`:
    .venv/bin/python bench/opcua_estop.py      (about 4 minutes)
Called by `make bench` (bench/run.py) and alone by `bench/run.py --opcua`.
"""
import asyncio
import datetime
import json
import os
import random
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from common import OUT, ROOT, machine, put_section  # bench/common.py (it puts tests/integration on the path)

DOC = os.path.join(ROOT, "docs", "performance.md")
JSON = os.path.join(OUT, "opcua.json")
TITLE = "## OPC UA: E-stop press to a subscription's notification (ms)"
GOAL_S = 0.200  # issue 14: a subscription sees EmergencyStop within 200 ms of a sim E-stop press
CELLS = int(os.environ.get("OPCUA_CELLS", "5"))
PRESSES = int(os.environ.get("OPCUA_PRESSES", "20"))


def pct(xs, p):
    xs = sorted(xs)
    return xs[min(len(xs) - 1, int(round(p / 100.0 * (len(xs) - 1))))]


async def presses(opc, n):
    from asyncua import ua  # noqa: PLC0415 (the test venv)
    from test_gateway import booted  # noqa: PLC0415
    from test_opcua import Nodes, client, wait_value  # noqa: PLC0415
    p = await booted(opc.cell)
    assert await p.command("reset") == "OK"
    await p.state("IDLE")
    seen = asyncio.Queue()

    class Handler:
        def datachange_notification(self, node, val, data):
            seen.put_nowait((time.monotonic(), val))

    delays = []
    async with client(opc.url) as c:
        nodes = await Nodes.of(c)
        estop = await nodes.estop_node()
        await wait_value(estop, lambda dv: dv.Value.Value is False, what="EmergencyStop false after reset")
        sub = await c.create_subscription(ua.CreateSubscriptionParameters(RequestedPublishingInterval=20,
                                                                          RequestedMaxKeepAliveCount=100,
                                                                          RequestedLifetimeCount=1000), Handler())
        revised = sub.parameters.RequestedPublishingInterval  # the server's revised value, copied back by asyncua
        await sub.subscribe_data_change(estop, sampling_interval=0)
        _, v = await asyncio.wait_for(seen.get(), 5)
        assert v is False
        for k in range(n):
            await asyncio.sleep(random.uniform(0.0, 0.1))  # a random phase against the status push and publishing
            pressed_at = time.monotonic()
            assert (await p.sim(set={"estop.a": 0, "estop.b": 0}))["result"] == "OK"
            t, v = await asyncio.wait_for(seen.get(), 5)
            assert v is True, (k, v)
            delays.append((t - pressed_at) * 1000.0)
            assert (await p.sim(set={"estop.a": 1, "estop.b": 1}))["result"] == "OK"
            await p.state("ESTOP_RESET_NEEDED")
            assert await p.command("reset") == "OK"
            _, v = await asyncio.wait_for(seen.get(), 5)
            assert v is False, (k, v)
        await sub.delete()
    await p.close()
    return delays, revised


def busy_loops(k, seconds):
    """k processes that keep a CPU busy each (bounded: they end by themselves after `seconds`),
    as a full `make test` keeps this 2-core machine busy."""
    code = f"import time\nend = time.monotonic() + {seconds}\nwhile time.monotonic() < end:\n    pass\n"
    return [subprocess.Popen([sys.executable, "-c", code]) for _ in range(k)]


def run_once(cells, n, loaded):
    """`cells` fresh `safestate run`s, `n` presses on each from its start on (as the functional
    test presses right after the start, when the adapter has just loaded its nodesets)."""
    from test_opcua import OpcCell  # noqa: PLC0415
    delays, first, revised = [], [], None
    for _ in range(cells):
        with tempfile.TemporaryDirectory(prefix="bench-opcua-") as d:
            opc = OpcCell(Path(d))
            busy = busy_loops(os.cpu_count() or 2, 600) if loaded else []
            try:
                got, revised = asyncio.run(presses(opc, n))
            finally:
                for b in busy:
                    b.kill()
                    b.wait()
                opc.cell.stop()
        delays += got
        first += got[:3]
    return {"cells": cells, "presses": len(delays), "revised_publishing_ms": revised,
            "delays_ms": [round(x, 2) for x in delays], "p50": pct(delays, 50), "p90": pct(delays, 90),
            "p99": pct(delays, 99), "max": max(delays), "first3_max": max(first)}


def measure(cells, n):
    return {"date": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
            "machine": machine(), "idle": run_once(cells, n, False), "loaded": run_once(cells, n, True),
            "busy_loops": os.cpu_count() or 2}


def goal_row(o):
    i, ld = o["idle"], o["loaded"]
    met = i["max"] < GOAL_S * 1000.0
    return (f"| A subscription sees EmergencyStop within 200 ms of a sim E-stop press (issue 14) | "
            f"{i['max']:.1f} ms at most in {i['presses']} presses on {i['cells']} fresh cells (p50 {i['p50']:.1f}); "
            f"with every core busy {ld['max']:.1f} ms at most (p50 {ld['p50']:.1f}) | {'met' if met else '**not met**'}"
            f"{'' if ld['max'] < GOAL_S * 1000.0 else ' (idle; not under load)'} |")


def section(o):
    i, ld = o["idle"], o["loaded"]
    row = lambda name, x: (f"| {name} | {x['cells']} × {x['presses'] // x['cells']} | {x['p50']:.1f} | {x['p90']:.1f} | "
                           f"{x['p99']:.1f} | {x['max']:.1f} | {x['first3_max']:.1f} | "
                           f"{'met' if x['max'] < GOAL_S * 1000.0 else '**not met**'} |")
    return [TITLE, "",
            f"Measured {o['date']} on {o['machine']} (`bench/opcua_estop.py`; `bench/run.py --opcua` measures this",
            "section alone). `safestate run` with its OPC UA adapter on the simulated cell; an asyncua client",
            "subscribes to `EmergencyStop` (requested publishing interval 20 ms, sampling interval 0: the server",
            f"revised the publishing interval to {i['revised_publishing_ms']:.0f} ms) and the E-stop is pressed on both",
            f"channels with the gateway's `sim` message, each press at a random phase: from just before the",
            "message is sent to the notification in the client's hands. The path: the gateway, the core's next",
            "cycle, the gateway's 50 Hz status push to the adapter, the adapter's variable, the subscription's",
            "next publish (up to one publishing interval), the client. Each series on fresh cells, pressed from",
            "their start on (the functional test presses right after the start, when the adapter has just loaded",
            f"its nodesets: *first 3* is the slowest of the first three presses of each cell). Once on an otherwise",
            f"idle host, once with {o['busy_loops']} busy loops keeping every core busy (as a full `make test` does here).", "",
            "| host | cells × presses | p50 | p90 | p99 | max | first 3, max | < 200 ms |",
            "|---|---|---|---|---|---|---|---|",
            row("idle", i), row(f"{o['busy_loops']} busy loops", ld), "",
            "The functional test `opcua_server` (`test_a_subscription_sees_emergency_stop_...`) asserts only a",
            "notification within 1 s (test_opcua.py `ESTOP_NOTIFY_MARGIN_S`), above the loaded maximum here",
            "with room for a host stall of the shared VM: during a full `make test` one press once took 201.9 ms",
            "against a 200 ms assertion (issue 40). Whether the 200 ms goal is met is this bench's to say.", ""]


def patch(o):
    text = open(DOC).read() if os.path.exists(DOC) else ""
    row = goal_row(o)
    if re.search(r"^\| A subscription sees EmergencyStop .*$", text, flags=re.M):
        text = re.sub(r"^\| A subscription sees EmergencyStop .*$", lambda _m: row, text, flags=re.M)
    else:
        text = re.sub(r"^(\| Command round trip .*)$", lambda m: m.group(1) + "\n" + row, text, count=1, flags=re.M)
    sec = "\n".join(section(o)) + "\n"
    text = put_section(text, TITLE, sec)
    with open(DOC, "w") as f:
        f.write(text)
    for name in ("idle", "loaded"):
        x = o[name]
        print(f"bench: OPC UA E-stop to notification, {name}: p50 {x['p50']:.1f} ms, p99 {x['p99']:.1f} ms, "
              f"max {x['max']:.1f} ms in {x['presses']} presses (goal < 200 ms: "
              f"{'met' if x['max'] < GOAL_S * 1000.0 else 'not met'})")
    print(f"bench: OPC UA rows of {os.path.relpath(DOC, ROOT)} rewritten")


def main():
    os.makedirs(OUT, exist_ok=True)
    if sys.argv[1:] == ["--render"]:
        patch(json.load(open(JSON)))
        return
    if sys.argv[1:]:
        raise SystemExit("usage: opcua_estop.py [--render]  (OPCUA_CELLS=N, default 5; OPCUA_PRESSES=N per cell, default 20)")
    if not 1 <= PRESSES <= 10000 or not 1 <= CELLS <= 100:
        raise SystemExit("OPCUA_PRESSES must be 1..10000 and OPCUA_CELLS 1..100")
    o = measure(CELLS, PRESSES)
    with open(JSON, "w") as f:
        json.dump(o, f, indent=1)
    patch(o)


if __name__ == "__main__":
    main()
