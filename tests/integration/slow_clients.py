"""Slow and idle clients against the gateway (issue 40), shared by the test
(test_gateway_limits.py) and the bench (bench/gw_admission.py); loopback only.

- `Load`: N connections held open by holder processes (each holds at most PER_HOLDER, so
  the test's own RLIMIT_NOFILE never matters): `idle` connections send nothing; `slow`
  ones (slowloris) send one byte of a request head every SLOW_PERIOD_S seconds, a head
  that never ends. With `reopen`, a connection the gateway closes is opened again (at most
  one reopen per connection every REOPEN_S), so the load stays at N while it is measured.
  Every holder stops by itself after its lifetime, and when its stdin closes.
- `fresh_get(port)`: the seconds from connect to the status line of `GET /api/status`.
- `pendant_hello(port)`: the seconds from connect to the `welcome` of a hello as the
  pendant (upgrade, then hello), closed politely after.

Run a holder alone: python slow_clients.py hold PORT idle|slow N REOPEN LIFETIME_S
"""

import asyncio
import json
import os
import select
import socket
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from wsraw import frame_at, masked  # noqa: E402

PER_HOLDER = 400       # connections per holder process (well inside a limit of 1024)
SLOW_PERIOD_S = 3.0    # slowloris: one request-head byte this often
REOPEN_S = 0.2         # a closed connection is opened again at most this often
SLOW_HEAD = b"GET /api/status HTTP/1.1\r\nHost: 127.0.0.1\r\nX-Slow: " + b"s" * 4096


# ---------------------------------------------------------------------------- holder process
async def hold_one(port, kind, reopen, stop, stats):
    """One connection slot: connect, stay (idle or slow), count how it ended; reopen."""
    loop = asyncio.get_running_loop()
    while not stop.is_set():
        opened = loop.time()
        try:
            r, w = await asyncio.wait_for(asyncio.open_connection("127.0.0.1", port), 10)
        except (OSError, asyncio.TimeoutError):
            stats["connect_failed"] += 1
            await asyncio.sleep(REOPEN_S)
            continue
        stats["open"] += 1
        stats["opened"] += 1
        sent = 0
        answer = b""
        try:
            while not stop.is_set():
                if kind == "slow" and not answer:
                    w.write(SLOW_HEAD[sent % len(SLOW_HEAD):sent % len(SLOW_HEAD) + 1])
                    sent += 1
                    period = SLOW_PERIOD_S
                else:
                    period = 1.0
                try:
                    data = await asyncio.wait_for(r.read(4096), period)
                except asyncio.TimeoutError:
                    continue  # still open, nothing said: next byte (slow) or look again (idle)
                if not data:
                    break
                answer += data
        except OSError:
            pass
        finally:
            stats["open"] -= 1
            w.close()
        if stop.is_set():
            break
        line = answer.split(b"\r\n", 1)[0].decode("latin-1")
        code = line.split(" ")[1] if line.startswith("HTTP/1.1 ") else ("closed" if not answer else "other")
        stats["closed_by_server"][code] = stats["closed_by_server"].get(code, 0) + 1
        stats["lifetimes"].append(round(loop.time() - opened, 2))
        if not reopen:
            break
        await asyncio.sleep(max(0.0, REOPEN_S - (loop.time() - opened)))


async def holder_main(port, kind, n, reopen, lifetime):
    loop = asyncio.get_running_loop()
    stop = asyncio.Event()
    stats = {"open": 0, "opened": 0, "connect_failed": 0, "closed_by_server": {}, "lifetimes": []}
    loop.call_later(lifetime, stop.set)
    loop.add_reader(sys.stdin.fileno(), stop.set)  # the parent closed our stdin (or wrote): stop
    tasks = [asyncio.create_task(hold_one(port, kind, reopen, stop, stats)) for _ in range(n)]
    t0 = loop.time()
    while stats["opened"] < n and not stop.is_set() and loop.time() - t0 < 30:
        await asyncio.sleep(0.01)
    print(json.dumps({"ready": stats["opened"]}), flush=True)
    await stop.wait()
    for t in tasks:
        t.cancel()
    await asyncio.gather(*tasks, return_exceptions=True)
    lt = sorted(stats.pop("lifetimes"))
    stats["lifetime_s"] = {"min": lt[0], "max": lt[-1], "median": lt[len(lt) // 2]} if lt else None
    print(json.dumps(stats), flush=True)


class Load:
    """N idle or slow connections held by holder processes; a context manager."""

    def __init__(self, port, kind, n, reopen=False, lifetime=120.0):
        assert kind in ("idle", "slow")
        self.port, self.kind, self.n, self.reopen, self.lifetime = port, kind, n, reopen, lifetime
        self.procs = []
        self.ready = 0
        self.stats = []

    def __enter__(self):
        per = [PER_HOLDER] * (self.n // PER_HOLDER) + ([self.n % PER_HOLDER] if self.n % PER_HOLDER else [])
        try:
            for k in per:
                self.procs.append(subprocess.Popen(
                    [sys.executable, __file__, "hold", str(self.port), self.kind, str(k), str(int(self.reopen)),
                     str(self.lifetime)], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True))
            for p in self.procs:
                ready, _, _ = select.select([p.stdout], [], [], 40)
                assert ready, "a holder did not report"
                self.ready += json.loads(p.stdout.readline())["ready"]
        except BaseException:
            self.__exit__(None, None, None)
            raise
        return self

    def __exit__(self, *exc):
        for p in self.procs:
            try:
                p.stdin.close()
            except OSError:
                pass
        for p in self.procs:
            try:
                p.wait(timeout=20)
                self.stats.append(json.loads(p.stdout.read().strip().splitlines()[-1]))
            except (subprocess.TimeoutExpired, ValueError, IndexError):
                p.kill()
                p.wait()
            p.stdout.close()
        return False

    def summary(self):
        closed = {}
        for s in self.stats:
            for k, v in s["closed_by_server"].items():
                closed[k] = closed.get(k, 0) + v
        return {"ready": self.ready, "opened": sum(s["opened"] for s in self.stats),
                "connect_failed": sum(s["connect_failed"] for s in self.stats), "closed_by_server": closed,
                "lifetime_s": [s["lifetime_s"] for s in self.stats]}


# ---------------------------------------------------------------------------- measurements
def _read_until(sock, buf, pred, deadline):
    while not pred(buf):
        left = deadline - time.monotonic()
        if left <= 0:
            raise TimeoutError("no answer in time")
        sock.settimeout(left)
        chunk = sock.recv(65536)
        if not chunk:
            raise ConnectionError(f"closed by the gateway after {bytes(buf[:80])!r}")
        buf += chunk
    return buf


def fresh_get(port, timeout=5.0):
    """(seconds to the complete answer of GET /api/status, status code); (None, why) on failure."""
    t0 = time.monotonic()
    deadline = t0 + timeout
    try:
        with socket.create_connection(("127.0.0.1", port), timeout=timeout) as s:
            s.sendall(f"GET /api/status HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nConnection: close\r\n\r\n".encode())
            buf = _read_until(s, bytearray(), lambda b: b"\r\n\r\n" in b, deadline)
            head = bytes(buf[:buf.index(b"\r\n\r\n")]).decode("latin-1")
            length = next((int(h.split(":", 1)[1]) for h in head.split("\r\n") if h.lower().startswith("content-length:")), 0)
            body_at = buf.index(b"\r\n\r\n") + 4
            _read_until(s, buf, lambda b: len(b) - body_at >= length, deadline)
            return time.monotonic() - t0, int(head.split(" ")[1])
    except (OSError, TimeoutError, ValueError) as e:
        return None, f"{type(e).__name__}: {e}"


def pendant_hello(port, timeout=5.0):
    """(seconds from connect to the pendant's welcome, the welcome); (None, why) on failure."""
    t0 = time.monotonic()
    deadline = t0 + timeout
    try:
        with socket.create_connection(("127.0.0.1", port), timeout=timeout) as s:
            s.sendall((f"GET /ws HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
                       "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n\r\n").encode())
            buf = _read_until(s, bytearray(), lambda b: b"\r\n\r\n" in b, deadline)
            end = buf.index(b"\r\n\r\n")
            head = bytes(buf[:end]).decode("latin-1")
            if " 101 " not in head.split("\r\n", 1)[0]:
                return None, f"upgrade answered {head.splitlines()[0]!r}"
            del buf[:end + 4]
            s.sendall(masked(1, b'{"type":"hello","role":"pendant","client":"issue-40"}'))
            while True:
                _read_until(s, buf, lambda b: frame_at(b, 0) is not None, deadline)
                opcode, start, ln = frame_at(buf, 0)
                body = bytes(buf[start:start + ln])
                del buf[:start + ln]
                if opcode == 0x8:
                    return None, f"closed {int.from_bytes(body[:2], 'big') if len(body) >= 2 else None}"
                if opcode == 0x1:
                    m = json.loads(body)
                    if m.get("type") in ("welcome", "error"):
                        took = time.monotonic() - t0
                        s.sendall(masked(0x8, (1000).to_bytes(2, "big")))
                        if m["type"] == "error":
                            return None, f"hello answered {m}"
                        _drain_close(s)
                        return took, m
    except (OSError, TimeoutError, ValueError) as e:
        return None, f"{type(e).__name__}: {e}"


def _drain_close(s, wait=1.0):
    """Reads until the gateway's close (the pendant's role is free again), at most `wait`."""
    deadline = time.monotonic() + wait
    try:
        while time.monotonic() < deadline:
            s.settimeout(max(0.01, deadline - time.monotonic()))
            if not s.recv(65536):
                return
    except OSError:
        return


if __name__ == "__main__" and len(sys.argv) == 7 and sys.argv[1] == "hold":
    asyncio.run(holder_main(int(sys.argv[2]), sys.argv[3], int(sys.argv[4]), sys.argv[5] == "1",
                            float(sys.argv[6])))
