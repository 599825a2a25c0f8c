"""Access and admission of the gateway (../shared/spec/protocol.md "Access and admission"),
from outside, against a real `safestate run` on loopback, as an attacker and a busy plant
would try it. Every server listens on a free loopback port; nothing leaves loopback.

Run:  SAFESTATE_BIN=build/bin/safestate python -m pytest tests/integration/test_access.py
"""

import asyncio
import http.client
import json
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
from test_gateway import (BIN, ROOT, Client, SafeState, booted, free_port, get_json, http_get,  # noqa: E402
                          pendant, run, try_status, wait_until)

try:  # websockets >= 13
    from websockets.asyncio.client import connect as ws_connect
except ImportError:  # pragma: no cover
    from websockets import connect as ws_connect
from websockets.exceptions import ConnectionClosed, InvalidStatus  # noqa: E402

TOKENS = {"SAFESTATE_PENDANT_TOKEN": "pendant-secret-1", "SAFESTATE_REMOTE_TOKEN": "remote-secret-2"}


@pytest.fixture
def cell(tmp_path):
    s = SafeState(tmp_path)
    yield s
    assert s.stop() == 0, s.output()


def raw_http(port, head, timeout=5.0):
    """Sends a raw request head, returns the status code of the answer (0: no answer)."""
    with socket.create_connection(("127.0.0.1", port), timeout=timeout) as s:
        s.sendall(head.encode())
        data = b""
        try:
            while b"\r\n" not in data:
                chunk = s.recv(4096)
                if not chunk:
                    break
                data += chunk
        except OSError:
            pass
    line = data.split(b"\r\n", 1)[0].split()
    return int(line[1]) if len(line) > 1 else 0


def upgrade_status(port, headers):
    """Status of a WebSocket upgrade request with these headers (101 when accepted)."""
    head = ("GET /ws HTTP/1.1\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
            "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n")
    for k, v in headers.items():
        head += f"{k}: {v}\r\n"
    return raw_http(port, head + "\r\n")


# ---------------------------------------------------------------------------- who may connect
def test_cross_origin_upgrade_and_request_refused(cell):
    p = cell.port
    own = {"Host": f"127.0.0.1:{p}"}
    assert upgrade_status(p, {**own, "Origin": "http://evil.example"}) == 403
    assert upgrade_status(p, {**own, "Origin": "null"}) == 403
    assert upgrade_status(p, {**own, "Origin": f"http://127.0.0.1:{p + 1}"}) == 403
    assert upgrade_status(p, {**own, "Origin": f"https://127.0.0.1:{p}"}) == 403
    assert upgrade_status(p, {**own, "Origin": f"http://127.0.0.1:{p}"}) == 101
    assert upgrade_status(p, {**own, "Origin": f"http://localhost:{p}"}) == 101
    assert upgrade_status(p, own) == 101  # no Origin: not a browser
    status, _, _ = http_get(p, "/api/events", headers={"Origin": "http://evil.example"})
    assert status == 403


def test_allow_origin_and_allow_host(tmp_path):
    s = SafeState(tmp_path, args=("--allow-origin", "https://hmi.plant.example",
                                  "--allow-host", "cell7.plant.example"))
    try:
        p = s.port
        assert upgrade_status(p, {"Host": f"127.0.0.1:{p}", "Origin": "https://hmi.plant.example"}) == 101
        assert upgrade_status(p, {"Host": f"127.0.0.1:{p}", "Origin": "https://other.plant.example"}) == 403
        assert upgrade_status(p, {"Host": f"cell7.plant.example:{p}"}) == 101
        assert upgrade_status(p, {"Host": f"cell8.plant.example:{p}"}) == 421
    finally:
        assert s.stop() == 0, s.output()


def test_foreign_host_refused(cell):
    """DNS rebinding: a page whose name now points at 127.0.0.1 sends its own name."""
    p = cell.port
    for path in ("/api/events", "/api/status", "/metrics", "/"):
        status, _, _ = http_get(p, path, headers={"Host": f"rebind.attacker.example:{p}"})
        assert status == 421, path
    assert upgrade_status(p, {"Host": f"rebind.attacker.example:{p}"}) == 421
    assert raw_http(p, "GET /api/status HTTP/1.0\r\n\r\n") == 421  # no Host at all
    status, _, _ = http_get(p, "/api/status", headers={"Host": f"localhost:{p}"})
    assert status == 200


def test_beyond_loopback_without_both_tokens_refuses_to_start(tmp_path):
    """Exits non-zero with a clear message, before any socket listens."""
    for env in ({}, {"SAFESTATE_PENDANT_TOKEN": "only-one"}, {"SAFESTATE_REMOTE_TOKEN": "only-one"}):
        port = free_port()
        clean = {k: v for k, v in os.environ.items() if not k.startswith("SAFESTATE_") or k == "SAFESTATE_BIN"}
        r = subprocess.run([BIN, "run", "--bind", "0.0.0.0", "--port", str(port), "--db",
                            str(tmp_path / "x.db")], env={**clean, **env}, cwd=str(ROOT),
                           capture_output=True, text=True, timeout=20)
        assert r.returncode != 0, r
        assert "refusing to listen on 0.0.0.0" in r.stderr and "SAFESTATE_PENDANT_TOKEN" in r.stderr, r.stderr
        assert try_status(port) is None


def test_token_file_and_unreadable_token_file(tmp_path):
    f = tmp_path / "pendant.token"
    f.write_text("from-a-file\n")
    s = SafeState(tmp_path, args=("--pendant-token-file", str(f)))
    try:
        async def main():
            c = await Client.connect(s.ws_url)
            assert (await c.hello("pendant", token="from-a-file\n"))["code"] == "BAD_TOKEN"
            assert (await c.hello("pendant", token="from-a-file"))["type"] == "welcome"
            await c.close()
        run(main())
    finally:
        assert s.stop() == 0, s.output()
    r = subprocess.run([BIN, "run", "--port", str(free_port()), "--pendant-token-file", str(tmp_path / "missing")],
                       cwd=str(ROOT), capture_output=True, text=True, timeout=20)
    assert r.returncode != 0 and "cannot read token file" in r.stderr, r.stderr


def test_bearer_on_api_and_metrics_beyond_loopback(tmp_path):
    s = SafeState(tmp_path, args=("--bind", "0.0.0.0"), env=TOKENS)
    try:
        p = s.port
        for path in ("/api/status", "/api/events", "/api/alarms", "/api/robot", "/metrics"):
            assert http_get(p, path)[0] == 401, path
            assert http_get(p, path, headers={"Authorization": "Bearer wrong"})[0] == 401, path
            assert http_get(p, path, headers={"Authorization": "Basic cGVuZGFudA=="})[0] == 401, path
            for tok in TOKENS.values():
                assert http_get(p, path, headers={"Authorization": f"Bearer {tok}"})[0] == 200, path
        assert http_get(p, "/")[0] == 200  # the HMI's page itself holds no data
    finally:
        assert s.stop() == 0, s.output()


def test_sim_needs_hello_and_remote_never_takes_the_pendant_role(cell):
    async def main():
        c = await Client.connect(cell.ws_url)
        r = await c.sim(set={"gate": "open"})
        assert r["type"] == "error" and r["code"] == "NOT_HELLO", r
        assert (await c.hello("observer"))["type"] == "welcome"
        r = await c.sim(set={"gate": "closed"})
        assert r["type"] == "reply" and r["result"] == "OK", r
        await c.close()
    run(main())


def test_constant_time_comparison_does_not_depend_on_the_secret(tmp_path):
    """Many wrong tokens of every length, all refused; the right one accepted. (The
    timing property itself is a property of same_token: its loop runs over what the
    client sent and never exits early; a timing measurement over loopback on a shared
    VM could not tell a few nanoseconds apart, so it is not attempted here.)"""
    env = {"SAFESTATE_PENDANT_TOKEN": "abcdefgh", "SAFESTATE_REMOTE_TOKEN": "r"}
    s = SafeState(tmp_path, env=env)
    try:
        async def main():
            c = await Client.connect(s.ws_url)
            for wrong in ("", "a", "abcdefg", "abcdefgh ", "abcdefghabcdefgh", "Abcdefgh", "abcdefgi", "r"):
                assert (await c.hello("pendant", token=wrong))["code"] == "BAD_TOKEN", wrong
            assert (await c.hello("pendant", token="abcdefgh"))["type"] == "welcome"
            await c.close()
        run(main())
    finally:
        assert s.stop() == 0, s.output()


# ---------------------------------------------------------------------------- admission
def test_100_connections_without_hello_and_the_pendant_still_gets_in(cell):
    async def main():
        squatters = []
        for _ in range(100):
            try:
                squatters.append(await ws_connect(cell.ws_url, open_timeout=10))
            except (InvalidStatus, OSError, ConnectionClosed):
                pass
        p = await pendant(cell)
        await p.state("ESTOP_RESET_NEEDED")
        assert await p.command("reset") == "OK"
        await p.close()
        for w in squatters:
            await w.close()
    run(main())


def test_hello_deadline_closes_a_silent_connection(cell):
    async def main():
        w = await ws_connect(cell.ws_url, open_timeout=10)
        t0 = time.monotonic()
        got = []
        try:
            async for raw in w:
                got.append(json.loads(raw))
        except ConnectionClosed:
            pass
        took = time.monotonic() - t0
        assert 4.0 <= took <= 9.0, took
        assert got and got[-1]["type"] == "error" and got[-1]["code"] == "NOT_HELLO", got
    run(main())


def test_last_slot_is_kept_for_the_pendant(tmp_path):
    s = SafeState(tmp_path, args=("--max-clients", "4"))
    try:
        async def main():
            others = [await pendant(s, "observer"), await pendant(s, "observer"), await pendant(s, "remote")]
            fourth = await Client.connect(s.ws_url)
            m = await fourth.hello("observer")
            assert m["type"] == "error" and m["code"] == "ROLE_TAKEN", m
            with pytest.raises(AssertionError, match="connection closed"):
                await fourth.wait_for(lambda m: False, timeout=5)
            p = await pendant(s)
            await p.state("ESTOP_RESET_NEEDED")
            assert await p.command("reset") == "OK"
            for c in others + [p]:
                await c.close()
        run(main())
    finally:
        assert s.stop() == 0, s.output()


def test_idle_http_connections_do_not_lock_the_pendant_out(cell):
    idle = [socket.create_connection(("127.0.0.1", cell.port)) for _ in range(100)]
    try:
        async def main():
            p = await pendant(cell)
            await p.state("ESTOP_RESET_NEEDED")
            await p.close()
        run(main())
        assert http_get(cell.port, "/api/status")[0] == 200
    finally:
        for s in idle:
            s.close()


def test_overlong_url_and_head(cell):
    p = cell.port
    assert raw_http(p, f"GET /{'a' * 3000} HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n") == 414
    assert raw_http(p, f"GET /{'a' * 20000} HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n") == 414
    assert raw_http(p, f"GET / HTTP/1.1\r\nHost: 127.0.0.1\r\nX-Big: {'b' * 9000}\r\n\r\n") == 431
    many = "".join(f"X-H{i}: {'c' * 100}\r\n" for i in range(100))
    assert raw_http(p, f"GET / HTTP/1.1\r\nHost: 127.0.0.1\r\n{many}\r\n") == 431
    assert http_get(p, "/api/status")[0] == 200


def test_every_oversize_frame_gets_too_large(cell):
    async def main():
        c = await pendant(cell, "observer")
        for size in (4097, 70 * 1024, 900 * 1024):
            e = await c.error("x" * size)
            assert e["code"] == "TOO_LARGE" and str(size) in e["detail"], (size, e)
        assert (await c.hello("observer"))["type"] == "welcome"  # still served
        big = await Client.connect(cell.ws_url)
        await big.send("y" * (3 * 1024 * 1024))
        await big.wait_for(lambda m: m.get("code") == "TOO_LARGE", what="TOO_LARGE for 3 MiB")
        await c.close()
    run(main())


# ---------------------------------------------------------------------------- fairness
def event_ids(port):
    ids = []
    after = 0
    while True:
        page = get_json(port, f"/api/events?after={after}&limit=500")
        if not page:
            return ids
        ids += [e["id"] for e in page]
        after = page[-1]["id"]


def test_observer_commands_answered_by_the_gateway_and_not_logged(cell):
    async def main():
        p = await booted(cell)
        await p.close()
        time.sleep(0.5)
        before = event_ids(cell.port)
        o = await pendant(cell, "observer")
        n = 2000
        for i in range(n):
            await o.send({"type": "command", "seq": 100000 + i, "cmd": "servo_on"})
        await o.wait_for(lambda m: m["type"] == "reply" and m["seq"] == 100000 + n - 1, timeout=60,
                         what="the last reply")
        replies = [m for m in o.messages if m["type"] == "reply"]
        assert len(replies) == n and {m["result"] for m in replies} == {"NOT_CONTROL_OWNER"}
        assert sorted(m["seq"] for m in replies) == list(range(100000, 100000 + n))
        time.sleep(0.5)
        assert event_ids(cell.port) == before, "an observer's command reached the event log"
        await o.close()
    run(main())


def test_events_paged_at_most_500_with_next(cell):
    async def main():
        p = await booted(cell)
        for i in range(300):
            await p.send({"type": "command", "seq": i, "cmd": "start"})  # refused by the core, logged
            await asyncio.sleep(0.005)  # within the gateway's 250 records/s per client
        await p.wait_for(lambda m: m["type"] == "reply" and m["seq"] == 299, timeout=10)
        await p.close()
    run(main())
    run(main())
    conn = http.client.HTTPConnection("127.0.0.1", cell.port, timeout=5)
    conn.request("GET", "/api/events?limit=1000")
    r = conn.getresponse()
    page = json.loads(r.read())
    assert len(page) == 500, len(page)
    assert r.getheader("X-Next-After") == str(page[-1]["id"])
    assert f"after={page[-1]['id']}" in r.getheader("Link") and 'rel="next"' in r.getheader("Link")
    conn.close()
    assert all(e["blackbox"] is None or isinstance(e["blackbox"], str) for e in page)


# ---------------------------------------------------------------------------- operations
def test_second_run_on_the_same_port_refuses_and_names_the_first(cell):
    r = subprocess.run([BIN, "run", "--port", str(cell.port), "--db", str(Path(cell.db).with_name("other.db"))],
                       cwd=str(ROOT), capture_output=True, text=True, timeout=30)
    assert r.returncode != 0, r
    assert f"process {cell.proc.pid}" in r.stderr, r.stderr
    assert cell.proc.poll() is None
    s = get_json(cell.port, "/api/status")
    assert s["core_pid"] == cell.proc.pid
    t0 = s["t"]
    wait_until(lambda: (x := try_status(cell.port)) and x["t"] > t0 + 100, 5, "the first to keep cycling")


def test_gateway_restarts_are_counted_and_backed_off(cell):
    assert get_json(cell.port, "/api/status")["gateway_restarts"] == 0
    times = []
    for k in range(3):
        gw = get_json(cell.port, "/api/status")["gateway_pid"]
        os.kill(gw, signal.SIGKILL)
        t0 = time.monotonic()
        wait_until(lambda: (s := try_status(cell.port)) and s["gateway_pid"] != gw, 20, "the restarted gateway")
        times.append(time.monotonic() - t0)
    assert get_json(cell.port, "/api/status")["gateway_restarts"] == 3
    assert times[2] > times[0] + 1.0, times  # 0.5 s, 1 s, 2 s


def test_kill_9_of_the_gateway_during_a_burst_loses_no_event(cell):
    """Each command the core answers leaves a command event; killed mid-burst, the
    gateway's successor must log every one exactly once: the events' core cycles and
    commands, in order, with no gap in the transitions' chain and no duplicate."""
    async def burst(stop):
        while not stop.is_set():
            try:
                p = await pendant(cell)
            except Exception:
                await asyncio.sleep(0.05)
                continue
            try:
                i = 0
                while not stop.is_set():
                    i += 1
                    await p.send({"type": "command", "seq": i, "cmd": "reset"})
                    await p.send({"type": "sim", "seq": -i, "set": {"estop.a": i % 2, "estop.b": i % 2}})
                    await asyncio.sleep(0.002)
            except (ConnectionClosed, OSError):
                pass

    async def main():
        stop = asyncio.Event()
        task = asyncio.create_task(burst(stop))
        await asyncio.sleep(1.0)
        gw = get_json(cell.port, "/api/status")["gateway_pid"]
        os.kill(gw, signal.SIGKILL)
        await asyncio.sleep(2.5)
        stop.set()
        await task
    run(main())
    time.sleep(1.0)
    events = []
    after = 0
    while page := get_json(cell.port, f"/api/events?after={after}&limit=500"):
        events += page
        after = page[-1]["id"]
    ids = [e["id"] for e in events]
    assert ids == list(range(ids[0], ids[0] + len(ids))), "ids not contiguous"
    keys = [(e["t"], e["kind"], json.dumps(e["data"], sort_keys=True)) for e in events]
    assert len(set(keys)) == len(keys), "an event logged twice"
    ts = [e["t"] for e in events]
    assert ts == sorted(ts), "events out of the core's order"
    chain = [e["data"] for e in events if e["kind"] == "transition"]
    assert len(chain) > 10, len(chain)
    for a, b in zip(chain, chain[1:]):
        assert a["to"] == b["from"], f"a transition is missing between {a} and {b}"
    assert get_json(cell.port, "/api/status")["gateway_restarts"] == 1


def test_websocket_framing_ping_fragments_and_protocol_errors(cell):
    """The gateway frames RFC 6455 itself after the handshake: pings are answered,
    fragmented messages are put together, a frame a client must not send closes with 1002."""
    async def main():
        c = await pendant(cell, "observer")
        pong = await c.ws.ping(b"alive?")
        await asyncio.wait_for(pong, 5)
        mark = c.mark()
        await c.ws.send(['{"type":"command",', '"seq":77,', '"cmd":"reset"}'])  # three frames, one message
        r = await c.wait_for(lambda m: m["type"] == "reply" and m["seq"] == 77, since=mark, what="the reply")
        assert r["result"] == "NOT_CONTROL_OWNER"
        await c.close()

        s = socket.create_connection(("127.0.0.1", cell.port), timeout=5)
        s.sendall(b"GET /ws HTTP/1.1\r\nHost: 127.0.0.1\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
                  b"Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n\r\n")
        head = b""
        while b"\r\n\r\n" not in head:
            head += s.recv(1)
        assert b" 101 " in head.split(b"\r\n")[0], head
        s.sendall(b"\x81\x05hello")  # unmasked: clients must mask (RFC 6455 5.1)
        data = b""
        while True:
            chunk = s.recv(4096)
            if not chunk:
                break
            data += chunk
        s.close()
        assert b"\x88\x02\x03\xea" in data, data  # close 1002, protocol error
    run(main())
