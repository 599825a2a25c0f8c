"""The gateway's limits seen from outside (../shared/spec/protocol.md "Roles", "Access and
admission", "Fairness"), each against a real `safestate run` on the simulated cell:

- `sim` only from a loopback peer: the gateway bound beyond loopback (with both tokens, from
  the environment), reached over a veth pair between two network namespaces this test creates
  and removes (needs root; skipped otherwise);
- the hello deadline counts from the connection, not from the client's last byte;
- an observer flooding refused commands is slowed, and the other clients do not notice;
- the per-client record rate (250/s) gives QUEUE_FULL, with far fewer than 64 commands in flight;
- 300 slowloris connections, and 1100 idle ones (beyond the gateway's 1024 descriptors),
  never keep the pendant or a fresh request out (issue 40), and the bounds show in /metrics.

Run:  SAFESTATE_BIN=build/bin/safestate .venv/bin/python -m pytest tests/integration/test_gateway_limits.py
"""

import asyncio
import json
import os
import re
import subprocess
import sys
import tempfile
import time
import uuid
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
from test_gateway import BIN, ROOT, SafeState, booted, pendant, run  # noqa: E402

try:  # websockets >= 13
    from websockets.asyncio.client import connect as ws_connect
except ImportError:  # pragma: no cover
    from websockets import connect as ws_connect
from websockets.exceptions import ConnectionClosed  # noqa: E402

TOKENS = {"SAFESTATE_PENDANT_TOKEN": "pendant-secret-25", "SAFESTATE_REMOTE_TOKEN": "remote-secret-25"}


@pytest.fixture
def cell(tmp_path):
    s = SafeState(tmp_path)
    yield s
    assert s.stop() == 0, s.output()


# ---------------------------------------------------------------------------- sim from afar
# Run inside a namespace by `ip netns exec`: hello as the pendant with the token from the
# environment (never on a command line), then one `sim`; prints what answered each.
SIM_CLIENT = r'''
import asyncio, json, os, sys, time
from websockets.asyncio.client import connect

async def main(url):
    deadline = time.monotonic() + 20
    while True:
        try:
            ws = await connect(url, open_timeout=5)
            break
        except OSError:
            if time.monotonic() > deadline:
                raise
            await asyncio.sleep(0.1)
    async def answer(pred):
        while True:
            m = json.loads(await asyncio.wait_for(ws.recv(), 10))
            if pred(m):
                return m
    await ws.send(json.dumps({"type": "hello", "role": "pendant", "client": "netns",
                              "token": os.environ["SAFESTATE_PENDANT_TOKEN"]}))
    welcome = await answer(lambda m: m["type"] in ("welcome", "error"))
    await answer(lambda m: m["type"] == "status" and m["state"] != "BOOT")
    await ws.send(json.dumps({"type": "sim", "seq": 7, "set": {"gate": "open"}}))
    sim = await answer(lambda m: m["type"] == "error" or (m["type"] == "reply" and m["seq"] == 7))
    await ws.close()
    print(json.dumps({"welcome": welcome, "sim": sim}))

asyncio.run(main(sys.argv[1]))
'''


def sh(*args, check=True):
    return subprocess.run(args, check=check, capture_output=True, text=True, timeout=30)


@pytest.mark.skipif(os.geteuid() != 0, reason="needs root: network namespaces")
def test_sim_from_a_non_loopback_peer_is_not_simulated():
    """The gateway listens on 0.0.0.0 in namespace `g` (10.25.0.1 on a veth); a pendant with
    the right token connects from namespace `c` (10.25.0.2): its `sim` gets NOT_SIMULATED and
    the contacts do not change. The same from 127.0.0.1 in `g` is accepted (the cell is
    simulated: only the peer's address makes the difference)."""
    tag = uuid.uuid4().hex[:8]
    ns_g, ns_c = "ssgw-" + tag, "sscl-" + tag
    tmp = tempfile.TemporaryDirectory(prefix="ssgw-")
    proc = log = None
    port = 18080
    try:
        sh("ip", "netns", "add", ns_g)
        sh("ip", "netns", "add", ns_c)
        sh("ip", "-n", ns_g, "link", "add", "gw0", "type", "veth", "peer", "name", "cl0", "netns", ns_c)
        sh("ip", "-n", ns_g, "addr", "add", "10.25.0.1/24", "dev", "gw0")
        sh("ip", "-n", ns_c, "addr", "add", "10.25.0.2/24", "dev", "cl0")
        for ns, dev in ((ns_g, "gw0"), (ns_g, "lo"), (ns_c, "cl0"), (ns_c, "lo")):
            sh("ip", "-n", ns, "link", "set", dev, "up")
        script = Path(tmp.name, "sim_client.py")
        script.write_text(SIM_CLIENT)
        log = open(Path(tmp.name, "run.log"), "w")
        env = {**os.environ, **TOKENS}
        proc = subprocess.Popen(["ip", "netns", "exec", ns_g, BIN, "run", "--bind", "0.0.0.0", "--port", str(port),
                                 "--db", str(Path(tmp.name, "ev.db")), "--cycle-us", "1000", "--no-opcua"],
                                stdout=log, stderr=subprocess.STDOUT, cwd=str(ROOT), env=env)

        def client(ns, host):
            r = subprocess.run(["ip", "netns", "exec", ns, sys.executable, str(script), f"ws://{host}:{port}/ws"],
                               capture_output=True, text=True, timeout=60, env=env)
            assert r.returncode == 0, (r.stderr, Path(tmp.name, "run.log").read_text())
            return json.loads(r.stdout.strip().splitlines()[-1])

        far = client(ns_c, "10.25.0.1")
        assert far["welcome"]["type"] == "welcome" and far["welcome"]["role"] == "pendant", far
        assert far["sim"]["type"] == "error" and far["sim"]["code"] == "NOT_SIMULATED", far
        assert "loopback" in far["sim"]["detail"], far
        near = client(ns_g, "127.0.0.1")
        assert near["welcome"]["type"] == "welcome", near
        assert near["sim"] == {"type": "reply", "seq": 7, "result": "OK"}, near
        assert TOKENS["SAFESTATE_PENDANT_TOKEN"] not in Path(tmp.name, "run.log").read_text()
    finally:
        if proc is not None and proc.poll() is None:
            proc.terminate()
            try:
                proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
        if log is not None:
            log.close()
        sh("ip", "netns", "del", ns_c, check=False)
        sh("ip", "netns", "del", ns_g, check=False)
        tmp.cleanup()


# ---------------------------------------------------------------------------- hello deadline
def test_hello_deadline_counts_from_the_connection_not_the_last_byte(cell):
    """Two clients that never say hello but keep talking, one with WebSocket pings every
    second, one with a command (refused NOT_HELLO) every second: each gets NOT_HELLO "no
    hello within 5 s" and is closed about 5 s after connecting."""
    async def busy(how):
        ws = await ws_connect(cell.ws_url, open_timeout=10, ping_interval=None)
        t0 = time.monotonic()
        got = []

        async def reader():
            try:
                async for raw in ws:
                    got.append(json.loads(raw))
            except ConnectionClosed:
                pass
        rd = asyncio.create_task(reader())
        sent = 0
        while not rd.done() and time.monotonic() - t0 < 12:
            try:
                if how == "ping":
                    await ws.ping()
                else:
                    await ws.send(json.dumps({"type": "command", "seq": sent, "cmd": "reset"}))
                sent += 1
            except ConnectionClosed:
                break
            await asyncio.wait([rd], timeout=1.0)
        await asyncio.wait_for(rd, 5)
        return time.monotonic() - t0, sent, got

    async def main():
        return await asyncio.gather(busy("ping"), busy("frames"))
    for how, (took, sent, got) in zip(("ping", "frames"), run(main())):
        assert sent >= 4, (how, sent)  # it did keep the connection busy
        assert got and got[-1]["type"] == "error" and got[-1]["code"] == "NOT_HELLO", (how, got)
        assert "within 5 s" in got[-1]["detail"], (how, got[-1])
        assert 4.0 <= took <= 7.5, (how, took)
        print(f"{how}: closed {took:.2f} s after connecting, {sent} sent")


# ---------------------------------------------------------------------------- flooding observer
def test_an_observer_flooding_commands_is_slowed_and_others_do_not_notice(cell):
    async def main():
        p = await booted(cell)
        watcher = await pendant(cell, "observer")
        arrivals = []
        stop = asyncio.Event()

        async def watch():  # status arrival times of another client, during the flood
            i = len(watcher.messages)
            while not stop.is_set():
                while i < len(watcher.messages):
                    if watcher.messages[i]["type"] == "status":
                        arrivals.append(time.monotonic())
                    i += 1
                await asyncio.sleep(0.002)
        w = asyncio.create_task(watch())

        flood = await ws_connect(cell.ws_url, open_timeout=10)
        await flood.send(json.dumps({"type": "hello", "role": "observer", "client": "flood"}))
        replies = []

        async def count():
            try:
                async for raw in flood:
                    m = json.loads(raw)
                    if m["type"] == "reply":
                        replies.append((time.monotonic(), m["result"]))
            except ConnectionClosed:
                pass
        cr = asyncio.create_task(count())
        await asyncio.sleep(0.3)
        n = 2000
        t0 = time.monotonic()
        for i in range(n):
            await flood.send(json.dumps({"type": "command", "seq": i, "cmd": "servo_on"}))
        sent_in = time.monotonic() - t0
        await asyncio.sleep(max(0.0, t0 + 2.0 - time.monotonic()))
        stop.set()
        await w
        await flood.close()
        await asyncio.wait_for(cr, 10)
        # the pendant was not disturbed either: its command is answered by the core
        assert await p.command("reset") == "OK"
        await p.close()
        await watcher.close()
        return t0, sent_in, replies, arrivals

    t0, sent_in, replies, arrivals = run(main())
    in_1s = sum(1 for t, _ in replies if t <= t0 + 1.0)
    assert {r for _, r in replies} == {"NOT_CONTROL_OWNER"}, {r for _, r in replies}
    print(f"2000 commands sent in {sent_in:.3f} s; answered within 1 s: {in_1s}, within 2 s: {len(replies)}")
    assert sent_in < 1.0, sent_in  # the flood really was within a second
    assert in_1s < 1000, f"{in_1s} of 2000 refused commands answered within a second: the observer is not slowed"
    window = [t for t in arrivals if t0 <= t <= t0 + 2.0]
    gaps = [b - a for a, b in zip(window, window[1:])]
    rate = len(window) / 2.0
    print(f"another client's status during the flood: {rate:.1f} Hz, worst gap {max(gaps) * 1000:.0f} ms")
    assert rate >= 45.0, rate
    assert max(gaps) <= 0.25, max(gaps)


# ---------------------------------------------------------------------------- record rate
def test_a_pendant_above_250_records_a_second_gets_queue_full(cell):
    """Never more than 4 commands in flight (the in-flight cap is 64), each batch's replies
    awaited before the next: above 250 a second the gateway answers QUEUE_FULL itself, and
    the commands it lets through in the window stay within the token bucket (64 + 250/s)."""
    async def main():
        p = await booted(cell)
        results = []
        seq = 1000
        t0 = time.monotonic()
        while time.monotonic() - t0 < 1.5:
            batch = list(range(seq, seq + 4))
            seq += 4
            mark = p.mark()
            for s in batch:
                await p.send({"type": "command", "seq": s, "cmd": "start"})  # refused by the core, in ESTOP_RESET_NEEDED
            for s in batch:
                m = await p.wait_for(lambda m, s=s: m["type"] == "reply" and m["seq"] == s, since=mark,
                                     what=f"the reply to {s}")
                results.append(m["result"])
        took = time.monotonic() - t0
        await asyncio.sleep(0.5)  # the bucket fills again
        again = await p.command("start")
        await p.close()
        return results, took, again

    results, took, again = run(main())
    full = results.count("QUEUE_FULL")
    through = len(results) - full
    print(f"{len(results)} commands in {took:.2f} s ({len(results) / took:.0f}/s): {through} through, {full} QUEUE_FULL")
    assert len(results) / took > 400, "the client did not send well above 250 commands a second"
    assert full > 0, "no QUEUE_FULL above 250 records a second"
    assert through <= 64 + 250 * took + 10, (through, took)
    assert through >= 250 * took * 0.8, (through, took)  # the limit is 250/s, not less
    assert again != "QUEUE_FULL", again


# ---------------------------------------------------------------------------- slow and idle clients
# Issue 40: slowloris connections (a head byte every 3 s) and idle ones (no byte at all, more
# of them than the gateway has descriptors) must never keep the pendant or a fresh request
# out. The gateway runs with RLIMIT_NOFILE 1024, soft and hard (a common default, and one it
# cannot raise); the load is kept up while it is measured (a connection the gateway closes is
# opened again, as an attacker would). The times are bench/gw_admission.py's (a few ms, tens
# at most, docs/performance.md); 0.5 s is the bound, tens of times what is measured.
SERVED_S = 0.5
TRIALS = 5


def gateway_metrics(port):
    from test_gateway import http_get  # noqa: PLC0415
    status, _, body = http_get(port, "/metrics")
    assert status == 200, status
    return {k: float(v) for k, v in re.findall(r"(?m)^(safestate_gateway_\w+) (\S+)$", body)}


def served_during(port, load, gap=0.3):
    """TRIALS fresh GETs and pendant hellos during the load, `gap` s apart: each within SERVED_S."""
    from slow_clients import fresh_get, pendant_hello  # noqa: PLC0415
    gets, hellos = [], []
    for _ in range(TRIALS):
        t, why = fresh_get(port)
        assert t is not None and why == 200, f"a fresh GET /api/status during {load}: {why}"
        gets.append(t)
        t, why = pendant_hello(port)
        assert t is not None, f"the pendant's hello during {load}: {why}"
        assert why["role"] == "pendant", why
        hellos.append(t)
        time.sleep(gap)
    print(f"during {load}: fresh GET {1000 * max(gets):.1f} ms at most, pendant welcome "
          f"{1000 * max(hellos):.1f} ms at most ({TRIALS} each)")
    assert max(gets) < SERVED_S, gets
    assert max(hellos) < SERVED_S, hellos


def test_300_slowloris_connections_and_the_pendant_and_a_fresh_request_are_served(tmp_path):
    from slow_clients import Load  # noqa: PLC0415
    s = SafeState(tmp_path, nofile=1024)
    try:
        with Load(s.port, "slow", 300, reopen=True, lifetime=60) as load:
            assert load.ready == 300, load.ready
            time.sleep(0.5)
            # 5 trials over 4 s: across the 3 s deadline, while the 408s go out and the
            # slowloris connections are opened again.
            served_during(s.port, "300 slowloris connections", gap=0.8)
            m = gateway_metrics(s.port)
            # The slowloris connections (opened again) are held, waiting for their heads, inside the bounds.
            assert m["safestate_gateway_http_waiting"] >= 250, m
            assert m["safestate_gateway_http_waiting_peer_peak"] <= m["safestate_gateway_http_waiting_per_peer_max"], m
            assert m["safestate_gateway_first_head_limit_seconds"] <= 5, m
        summary = load.summary()
        print(f"300 slowloris: {summary}")
        # Each was answered 408 once its head was late (about 3 s), none kept for 10 s or more.
        assert summary["closed_by_server"].get("408", 0) >= 300, summary
        assert set(summary["closed_by_server"]) <= {"408", "503"}, summary
        assert max(x["max"] for x in summary["lifetime_s"] if x) < 6.0, summary
    finally:
        assert s.stop() == 0, s.output()


def test_1100_idle_connections_beyond_the_descriptors_and_the_pendant_and_a_fresh_request_are_served(tmp_path):
    from slow_clients import Load  # noqa: PLC0415
    s = SafeState(tmp_path, nofile=1024)
    try:
        with Load(s.port, "idle", 1100, reopen=True, lifetime=60) as load:
            assert load.ready == 1100, load.ready
            time.sleep(0.5)
            served_during(s.port, "1100 idle connections")
            m = gateway_metrics(s.port)
        summary = load.summary()
        print(f"1100 idle: {summary}; metrics {m}")
        assert m["safestate_gateway_fd_limit"] == 1024, m
        assert m["safestate_gateway_connections_max"] < 1024, m
        assert m["safestate_gateway_connections"] <= m["safestate_gateway_connections_max"], m
        assert m["safestate_gateway_http_waiting_peer_peak"] <= m["safestate_gateway_http_waiting_per_peer_max"], m
        assert m["safestate_gateway_shed_total"] > 0, m
        # The oldest silent ones gave way in words (503), the rest timed out (408): none was
        # closed without an answer.
        assert set(summary["closed_by_server"]) <= {"503", "408"}, summary
        assert summary["closed_by_server"].get("503", 0) > 0, summary
    finally:
        assert s.stop() == 0, s.output()
