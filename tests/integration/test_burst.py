"""Bursts of clients connecting at once (issue 23, protocol.md "Access and admission"):
50, 200 and 500 WebSocket clients open their connections in the same instant, with the
gateway's default caps (--max-clients 64, --max-http 32). Every one must be either
admitted (hello -> welcome, then status at ~50 Hz) or refused in words: HTTP 503 with
Retry-After before the upgrade, or a WebSocket close 1013 ("try again later") after it.
Nothing else: no connection closed or reset without an answer, no other close code. The
core keeps cycling (status `t` keeps up with the wall clock, overruns in /metrics stay
under 1 % of the cycles), and a pendant
that connects in the middle of the 500-client burst gets in at its first attempt (its
reserved slot).

Timing-sensitive: LABEL load (run under the shared CPU lock). The clients live in
WORKERS child processes of this file (one Python process cannot serve 500 sockets at
once), all released by one "GO" line, so the burst is the gateway's, not the harness's;
each worker reports its own event-loop lag, so a starved client shows as such.

Run:  SAFESTATE_BIN=build/bin/safestate python -m pytest tests/integration/test_burst.py
"""

import asyncio
import json
import os
import re
import resource
import select
import socket
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from wsraw import frame_at, masked  # noqa: E402

WORKERS = int(os.environ.get("SAFESTATE_BURST_WORKERS", "4"))
MAX_CLIENTS = 64  # the gateway's default --max-clients; one slot is the pendant's
HOLD_S = 2.0      # an admitted client stays this long, counting its statuses
MIN_HZ = 40.0     # "status at ~50 Hz", measured over the hold
ANSWER_S = 20.0   # a client without an outcome after this is lost


# ---------------------------------------------------------------------------- worker
class Probe(asyncio.Protocol):
    """One client: a raw RFC 6455 client (the `websockets` library is too slow for 125 at
    once in one process) that records how the gateway answered it."""

    def __init__(self, port):
        self.port = port
        self.buf = bytearray()
        self.stage = "connected"  # -> "upgraded" -> "welcomed"
        self.errors = []
        self.statuses = []  # (seconds after the welcome, status t)
        self.welcome_at = None
        self.outcome = None
        self.detail = ""
        self.done = asyncio.get_running_loop().create_future()
        self.transport = None

    def connection_made(self, transport):
        self.transport = transport
        transport.write((f"GET /ws HTTP/1.1\r\nHost: 127.0.0.1:{self.port}\r\nUpgrade: websocket\r\n"
                         "Connection: Upgrade\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n"
                         "Sec-WebSocket-Version: 13\r\n\r\n").encode())

    def data_received(self, data):
        if self.outcome:
            return
        self.buf += data
        if self.stage == "connected":
            end = self.buf.find(b"\r\n\r\n")
            if end < 0:
                return
            head = bytes(self.buf[:end]).decode("latin-1")
            del self.buf[:end + 4]
            code = head.split(" ", 2)[1] if head.startswith("HTTP/1.1 ") else head[:40]
            if code == "101":
                self.stage = "upgraded"
                self.transport.write(masked(1, b'{"type":"hello","role":"observer","client":"burst"}'))
            elif code == "503" and re.search(r"(?im)^retry-after:\s*\d+\s*$", head):
                self.finish("refused 503", head.splitlines()[0])
                return
            else:
                self.finish("lost", f"HTTP answer {head.splitlines()[0]!r} (not 101, nor 503 with Retry-After)")
                return
        self.frames()

    def frames(self):
        buf, pos = self.buf, 0
        while not self.outcome and (f := frame_at(buf, pos)) is not None:
            opcode, start, ln = f
            body = bytes(buf[start:start + ln])
            pos = start + ln
            if opcode == 0x8:
                code = int.from_bytes(body[:2], "big") if len(body) >= 2 else None
                if code == 1013 and self.stage != "welcomed":
                    self.finish("refused 1013", f"after {self.errors}")
                else:
                    self.finish("lost", f"close {code} {body[2:]!r} at stage {self.stage}, errors {self.errors}")
            elif opcode == 0x9:
                self.transport.write(masked(0xA, body))
            elif opcode == 0x1:
                if body.startswith(b'{"type":"status"'):
                    if self.welcome_at is not None:
                        t = int(body[21:body.index(b",", 21)])
                        self.statuses.append((asyncio.get_running_loop().time() - self.welcome_at, t))
                elif body.startswith(b'{"type":"welcome"'):
                    self.stage = "welcomed"
                    self.welcome_at = asyncio.get_running_loop().time()
                    asyncio.get_running_loop().call_later(HOLD_S, self.leave)
                elif body.startswith(b'{"type":"error"'):
                    self.errors.append(json.loads(body).get("code"))
        del buf[:pos]

    def leave(self):
        if not self.outcome:
            self.transport.write(masked(0x8, (1000).to_bytes(2, "big")))
            self.finish("admitted", "")

    def connection_lost(self, exc):
        self.finish("lost", f"TCP closed without an answer at stage {self.stage} ({exc!r}), errors {self.errors}")

    def finish(self, outcome, detail):
        if self.outcome:
            return
        self.outcome, self.detail = outcome, detail
        self.done.set_result(None)
        if self.transport:
            self.transport.close()


async def probe(port):
    loop = asyncio.get_running_loop()
    try:
        _, p = await asyncio.wait_for(loop.create_connection(lambda: Probe(port), "127.0.0.1", port), ANSWER_S)
    except (OSError, asyncio.TimeoutError) as e:
        return {"outcome": "lost", "detail": f"connect failed: {e!r}", "statuses": []}
    try:
        await asyncio.wait_for(asyncio.shield(p.done), ANSWER_S)
    except asyncio.TimeoutError:
        p.finish("lost", f"no answer within {ANSWER_S} s at stage {p.stage}, errors {p.errors}")
    return {"outcome": p.outcome, "detail": p.detail, "statuses": p.statuses}


async def worker_main(port, n):
    loop = asyncio.get_running_loop()
    print("READY", flush=True)
    line = await loop.run_in_executor(None, sys.stdin.readline)
    assert line.strip() == "GO", line
    lag = [0.0]
    stop = asyncio.Event()

    async def monitor():
        # This worker's own loop: how late a 10 ms sleep wakes (the client starved of CPU).
        while not stop.is_set():
            t = loop.time()
            await asyncio.sleep(0.010)
            lag[0] = max(lag[0], loop.time() - t - 0.010)
    m = asyncio.create_task(monitor())
    out = await asyncio.gather(*(probe(port) for _ in range(n)))  # all at once: no spacing
    stop.set()
    await m
    print(json.dumps({"clients": out, "lag": lag[0]}), flush=True)


# ---------------------------------------------------------------------------- test
def metric(port, name):
    from test_gateway import http_get  # noqa: PLC0415
    body = http_get(port, "/metrics")[2]
    return float(re.search(rf"(?m)^{name} (\S+)$", body).group(1))


def burst(s, n, pendant_in_the_middle=False):
    """Releases n clients at once; returns their outcomes and, if asked, the pendant's."""
    from test_gateway import Client, run  # noqa: PLC0415
    workers = []
    try:
        per = [n // WORKERS + (1 if i < n % WORKERS else 0) for i in range(WORKERS)]
        for k in per:
            workers.append(subprocess.Popen([sys.executable, __file__, "worker", str(s.port), str(k)],
                                            stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True))
        for w in workers:
            ready, _, _ = select.select([w.stdout], [], [], 30)
            assert ready and w.stdout.readline().strip() == "READY", "a worker did not start"
        t0 = time.monotonic()
        for w in workers:
            w.stdin.write("GO\n")
            w.stdin.flush()
        pendant = None
        if pendant_in_the_middle:
            async def main():
                await asyncio.sleep(0.05)  # the burst is under way: connections pile up at the gateway
                p = await Client.connect(s.ws_url)
                w = await p.hello("pendant")
                await p.close()
                return w
            pendant = run(main())
        results, lags = [], []
        for w in workers:
            out, _ = w.communicate(timeout=ANSWER_S + 30)
            r = json.loads(out.strip().splitlines()[-1])
            results += r["clients"]
            lags.append(r["lag"])
        print(f"{n} at once: {time.monotonic() - t0:.2f} s; workers' worst loop lag "
              f"{1000 * max(lags):.0f} ms", flush=True)
        return results, pendant
    finally:
        for w in workers:
            if w.poll() is None:
                w.kill()
                w.wait()


def test_bursts_of_50_200_500_are_each_admitted_or_refused_in_words(tmp_path):
    from test_gateway import SafeState, get_json  # noqa: PLC0415

    # The clients' side: 500 sockets in 4 processes fit the usual 1024, but say so.
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    if soft < 4096 <= hard or hard == resource.RLIM_INFINITY:
        resource.setrlimit(resource.RLIMIT_NOFILE, (4096, hard))
    s = SafeState(tmp_path)  # the default caps: what a plant runs
    try:
        for n in (50, 200, 500):
            overruns0 = metric(s.port, "safestate_overruns_total")
            t0, w0 = get_json(s.port, "/api/status")["t"], time.monotonic()
            results, pendant = burst(s, n, pendant_in_the_middle=(n == 500))
            t1, w1 = get_json(s.port, "/api/status")["t"], time.monotonic()
            overruns = metric(s.port, "safestate_overruns_total") - overruns0
            counts = {}
            for r in results:
                counts[r["outcome"]] = counts.get(r["outcome"], 0) + 1
            print(f"{n} at once: {counts}; core cycles {t1 - t0}, overruns {overruns:.0f}", flush=True)
            lost = [r["detail"] for r in results if r["outcome"] == "lost"]
            assert not lost, f"{len(lost)} of {n} clients lost without an answer, e.g. {lost[:5]}"
            assert len(results) == n
            # Nothing else holds a slot: every client up to the cap less the pendant's slot gets in.
            assert counts.get("admitted", 0) == min(n, MAX_CLIENTS - 1), counts
            for r in results:
                if r["outcome"] != "admitted":
                    continue
                st = r["statuses"]
                ts = [t for _, t in st]
                assert ts == sorted(set(ts)), "status t does not advance"
                assert len(st) / HOLD_S >= MIN_HZ, f"an admitted client got status at {len(st) / HOLD_S:.0f} Hz"
            # The core's loop (1 ms cycles): its cycle count keeps up with the wall clock, and
            # overruns stay rare. Not zero: on this shared 2-core machine the landed code counts
            # 1-6 per burst too (an overrun is a late cycle, counted, not a lost one).
            assert t1 - t0 >= 0.9 * (w1 - w0) * 1000, f"the core ran {t1 - t0} cycles in {w1 - w0:.2f} s"
            assert overruns <= 0.01 * (t1 - t0), f"{overruns:.0f} core overruns in {t1 - t0} cycles"
            if pendant is not None:
                assert pendant["type"] == "welcome" and pendant["role"] == "pendant", pendant
    finally:
        assert s.stop() == 0, s.output()


# ---------------------------------------------------------------------------- the rules, one by one
def raw_upgrade(port):
    """A socket after its WebSocket upgrade request, and the head of the answer."""
    c = socket.create_connection(("127.0.0.1", port), timeout=5)
    c.sendall((f"GET /ws HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
               "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n\r\n").encode())
    buf = b""
    while b"\r\n\r\n" not in buf:
        chunk = c.recv(4096)
        assert chunk, f"closed without an answer to the upgrade: {buf!r}"
        buf += chunk
    head, rest = buf.split(b"\r\n\r\n", 1)
    return c, head.decode("latin-1"), rest


def close_code(c, rest=b""):
    """The code of the server's close frame (skipping any text frames before it)."""
    buf = rest
    while True:
        while len(buf) >= 2:
            ln = buf[1] & 0x7F
            hl = 4 if ln == 126 else 2
            if ln == 126 and len(buf) >= 4:
                ln = int.from_bytes(buf[2:4], "big")
            if len(buf) < hl + ln:
                break
            if buf[0] & 0x0F == 0x8:
                return int.from_bytes(buf[hl:hl + 2], "big")
            buf = buf[hl + ln:]
        chunk = c.recv(4096)
        assert chunk, "closed without a close frame"
        buf += chunk


def retry_after(head):
    return re.search(r"(?im)^retry-after:\s*(\d+)\s*$", head)


def test_a_full_lobby_makes_the_newcomer_wait_until_its_oldest_is_silent_for_1_s(tmp_path):
    from test_gateway import SafeState  # noqa: PLC0415
    s = SafeState(tmp_path, args=("--max-clients", "2"))  # a lobby of 2 upgraded, no hello yet
    socks = []
    try:
        a, ha, ra = raw_upgrade(s.port)
        b, hb, _ = raw_upgrade(s.port)
        socks += [a, b]
        assert " 101 " in ha and " 101 " in hb, (ha, hb)
        # Both just upgraded: neither is evicted at once; the newcomer waits until the oldest
        # has been silent for 1 s, which then gives its slot away in words (close 1013).
        t0 = time.monotonic()
        c, hc, _ = raw_upgrade(s.port)
        waited = time.monotonic() - t0
        socks.append(c)
        assert " 101 " in hc, hc
        assert 0.7 <= waited <= 2.5, f"upgraded after {waited:.2f} s"
        assert close_code(a, ra) == 1013
        b.settimeout(0.3)
        try:
            assert b.recv(1) != b"", "the younger one was closed too"
        except socket.timeout:
            pass  # still open: the younger one kept its slot
    finally:
        for x in socks:
            x.close()
        assert s.stop() == 0, s.output()


def test_waiting_connections_hold_no_service_slot_and_beyond_the_cap_a_request_waits_its_turn(tmp_path):
    """--max-http bounds requests in service (issue 40): connections that have not sent a
    complete request (idle, or a slowloris head) take none, so a GET with every one of them
    held is answered at once; a request beyond the cap waits in order until a slot frees."""
    from test_gateway import SafeState, http_get  # noqa: PLC0415
    s = SafeState(tmp_path, args=("--max-http", "1", "--max-clients", "2"))
    socks = []
    try:
        socks += [socket.create_connection(("127.0.0.1", s.port), timeout=5) for _ in range(2)]  # idle
        for x in socks[-2:]:
            x.sendall(b"GET /api/status HTTP/1.1\r\nHost: 127.0.0.1\r\n")  # and a head never ended
        socks += [socket.create_connection(("127.0.0.1", s.port), timeout=5) for _ in range(2)]
        time.sleep(0.1)
        t0 = time.monotonic()
        assert http_get(s.port, "/api/status")[0] == 200
        waited = time.monotonic() - t0
        assert waited < 0.5, f"a GET waited {waited:.2f} s behind connections that sent no request"
        # The one service slot held: an upgrade waiting for a lobby full of two fresh
        # squatters (the oldest gives way after 1 s of silence). A GET sent meanwhile waits
        # its turn, then is answered, not refused.
        a, ha, _ = raw_upgrade(s.port)
        b, hb, _ = raw_upgrade(s.port)
        socks += [a, b]
        assert " 101 " in ha and " 101 " in hb, (ha, hb)
        time.sleep(0.3)
        c = socket.create_connection(("127.0.0.1", s.port), timeout=5)
        socks.append(c)
        c.sendall((f"GET /ws HTTP/1.1\r\nHost: 127.0.0.1:{s.port}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
                   "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n\r\n").encode())
        time.sleep(0.05)  # c holds the slot
        t0 = time.monotonic()
        status, _, _ = http_get(s.port, "/api/status")
        waited = time.monotonic() - t0
        assert status == 200, status
        assert 0.4 <= waited <= 0.95, f"answered after {waited:.2f} s (the slot frees about 0.65 s after the GET)"
        assert c.recv(4096).startswith(b"HTTP/1.1 101 "), "the upgrade holding the slot"
    finally:
        for x in socks:
            x.close()
        assert s.stop() == 0, s.output()


if __name__ == "__main__" and len(sys.argv) == 4 and sys.argv[1] == "worker":
    asyncio.run(worker_main(int(sys.argv[2]), int(sys.argv[3])))
