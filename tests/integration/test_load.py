"""Fairness under load (../shared/spec/protocol.md "Fairness"): 500 observers admitted up to
the cap, each receiving status at >= 45 Hz with no gap over 250 ms for 10 s, while a
pendant sends 3 x 2,000 pipelined commands and gets exactly one reply to each.

Timing-sensitive: registered with the CTest LABEL `load` (run under the shared CPU lock;
the sanitizer presets exclude it). One Python process cannot read 500 sockets fast
enough, so the observers live in WORKERS child processes of this same file.

Run:  SAFESTATE_BIN=build/bin/safestate python -m pytest tests/integration/test_load.py
"""

import asyncio
import json
import os
import select
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from wsraw import frame_at, masked  # noqa: E402

OBSERVERS = int(os.environ.get("SAFESTATE_LOAD_OBSERVERS", "500"))
WORKERS = int(os.environ.get("SAFESTATE_LOAD_WORKERS", "5"))
WINDOW_S = 10.0
MIN_HZ = 45.0
MAX_GAP_S = 0.250
BURSTS = 3
BURST = 2000


# ---------------------------------------------------------------------------- worker
# A minimal RFC 6455 client on a raw asyncio protocol: the python `websockets` library
# costs tens of microseconds per message, and 500 observers receiving status at 50 Hz
# plus every event would measure this machine's Python, not the gateway. For the same
# reason the workers run on uvloop: on asyncio's own loop the five of them took about 1.5
# of the two cores, their loops lagged 30-160 ms, and the gateway (0.4 of a core) waited
# for the CPU (44-46 Hz); on uvloop they lag a few ms and the gateway gets 48-49 Hz.
class Observer(asyncio.Protocol):
    def __init__(self, ready, go, out):
        self.ready, self.go, self.out = ready, go, out
        self.buf = bytearray()
        self.upgraded = False
        self.welcomed = False
        self.arrivals = []
        self.cycles = []
        self.closed = False
        self.done = asyncio.get_running_loop().create_future()
        self.transport = None

    def connection_made(self, transport):
        self.transport = transport

    def send_text(self, text):
        self.transport.write(masked(0x1, text.encode()))

    def data_received(self, data):
        self.buf += data
        if not self.upgraded:
            end = self.buf.find(b"\r\n\r\n")
            if end < 0:
                return
            if b" 101 " not in self.buf[:end]:
                self.finish(f"upgrade refused: {bytes(self.buf[:end])!r}")
                return
            del self.buf[:end + 4]
            self.upgraded = True
            self.send_text(json.dumps({"type": "hello", "role": "observer", "client": "load"}))
        self.frames()

    def frames(self):
        buf, pos = self.buf, 0
        loop_time = asyncio.get_running_loop().time
        while (f := frame_at(buf, pos)) is not None:
            opcode, start, ln = f
            if opcode == 0x9:  # ping: pong with its payload
                self.transport.write(masked(0xA, bytes(buf[start:start + ln])))
            elif opcode == 0x8:
                self.finish("closed by the server")
                return
            elif buf.startswith(b'{"type":"status","t":', start):
                if self.go.is_set():
                    now = loop_time()
                    self.arrivals.append(now - self.go.t0)
                    # The core's cycle the status was read at: when the gateway built it.
                    digits = start + 21
                    end = buf.index(b",", digits, start + ln)
                    self.cycles.append(int(buf[digits:end]))
                    if now - self.go.t0 > WINDOW_S:
                        self.finish(None)
                        return
            elif not self.welcomed:
                if buf.startswith(b'{"type":"welcome"', start):
                    self.welcomed = True
                    self.ready()
                elif buf.startswith(b'{"type":"error"', start):
                    self.finish(f"hello refused: {bytes(buf[start:start + ln])!r}")
                    return
            pos = start + ln
        del buf[:pos]

    def connection_lost(self, exc):
        self.finish("connection lost")

    def finish(self, why):
        if self.done.done():
            return
        self.closed = why is not None
        self.out.append({"arrivals": self.arrivals, "cycles": self.cycles, "closed": self.closed, "why": why,
                         "lag": self.go.lag})
        self.done.set_result(None)
        if self.transport:
            self.transport.close()


async def observer(url, ready, go, out):
    host, port = "127.0.0.1", int(url.rsplit(":", 1)[1].split("/")[0])
    loop = asyncio.get_running_loop()
    _, proto = await loop.create_connection(lambda: Observer(ready, go, out), host, port)
    proto.transport.write((f"GET /ws HTTP/1.1\r\nHost: {host}:{port}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
                           "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n\r\n").encode())
    await proto.done


async def worker_main(url, n):
    go = asyncio.Event()
    go.t0 = 0.0
    go.lag = []
    count = 0

    def ready():
        nonlocal count
        count += 1
        if count == n:
            print("READY", flush=True)

    out = []
    tasks = []
    for _ in range(n):
        tasks.append(asyncio.create_task(observer(url, ready, go, out)))
        await asyncio.sleep(0.002)  # connect at a steady pace, not 125 SYNs at once
    loop = asyncio.get_running_loop()
    line = await loop.run_in_executor(None, sys.stdin.readline)
    assert line.strip() == "GO", line
    go.t0 = loop.time()
    go.set()
    go.lag = []

    async def lag():
        # This worker's own event loop: how late a 10 ms sleep wakes (the worker starved of CPU).
        while loop.time() - go.t0 < WINDOW_S:
            t = loop.time()
            await asyncio.sleep(0.010)
            go.lag.append((round(t - go.t0, 3), round(loop.time() - t - 0.010, 4)))
    monitor = asyncio.create_task(lag())
    await asyncio.wait_for(asyncio.gather(*tasks), WINDOW_S + 60)
    monitor.cancel()
    print(json.dumps(out), flush=True)


# ---------------------------------------------------------------------------- test
def cpu_seconds(port):
    """CPU time (user + system) the gateway has used, from /proc."""
    from test_gateway import get_json  # noqa: PLC0415
    gw = get_json(port, "/api/status")["gateway_pid"]
    fields = Path(f"/proc/{gw}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")

def diagnose(r, at, gap):
    """Who the worst gap is on: the cycles (ms) between the statuses around it say how far
    apart the gateway built them; the worker's own loop lag says whether the client was
    starved of CPU at that time."""
    if r is None:
        return "no observer received anything"
    a, c = r["arrivals"], r["cycles"]
    k = next((i for i, x in enumerate(a) if x > at), None)
    if k is None:
        return f"worst gap {gap * 1000:.0f} ms at the end of the window"
    built = (c[k] - c[k - 1]) if k > 0 else None
    lags = [lag for t, lag in r["lag"] if at - 0.05 <= t <= at + gap]
    return (f"worst gap {gap * 1000:.0f} ms from {at:.3f} s: the status after it was built "
            f"{'(first)' if built is None else f'{built} ms after the one before'}; "
            f"the worker's loop lag around it: max {1000 * max(lags, default=0):.0f} ms")


def test_500_observers_keep_their_status_while_a_pendant_bursts(tmp_path):
    from test_gateway import Client, SafeState, booted, run  # noqa: PLC0415

    s = SafeState(tmp_path, args=("--max-clients", str(OBSERVERS + 1)))
    workers = []
    try:
        per = OBSERVERS // WORKERS
        for _ in range(WORKERS):
            workers.append(subprocess.Popen([sys.executable, __file__, "worker", s.ws_url, str(per)],
                                            stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True))
        deadline = time.monotonic() + 60
        for w in workers:
            ready, _, _ = select.select([w.stdout], [], [], max(0.0, deadline - time.monotonic()))
            line = w.stdout.readline() if ready else "(nothing within 60 s)"
            assert line.strip() == "READY", f"a worker did not get its observers in: {line!r} {s.output()}"

        async def main():
            extra = await Client.connect(s.ws_url)
            m = await extra.hello("observer")
            assert m["type"] == "error" and m["code"] == "ROLE_TAKEN", m  # the cap, less the pendant's slot
            p = await booted(s)
            cpu0 = cpu_seconds(s.port)
            for w in workers:
                w.stdin.write("GO\n")
                w.stdin.flush()
            t0 = time.monotonic()
            for b in range(BURSTS):
                seqs = list(range(b * BURST + 1, (b + 1) * BURST + 1))
                mark = p.mark()
                for q in seqs:
                    await p.send({"type": "command", "seq": q, "cmd": "start"})
                got = 0

                def counted(m):
                    nonlocal got
                    got += m["type"] == "reply"
                    return got >= BURST
                await p.wait_for(counted, timeout=60, since=mark, what=f"the replies of burst {b + 1}")
                await asyncio.sleep(0.3)  # let the last replies' duplicates, if any, arrive
                print(f"burst {b + 1}: {time.monotonic() - t0:.2f} s after the start", flush=True)
                replies = [x["seq"] for x in p.messages[mark:] if x["type"] == "reply"]
                assert sorted(replies) == seqs, f"burst {b + 1}: not exactly one reply per command"
            assert time.monotonic() - t0 < WINDOW_S, "the bursts took longer than the window"
            await asyncio.sleep(max(0.0, WINDOW_S - (time.monotonic() - t0)))
            print(f"gateway CPU during the window: {cpu_seconds(s.port) - cpu0:.2f} s", flush=True)
            await p.close()
        run(main())

        results = []
        for w in workers:
            out, _ = w.communicate(timeout=WINDOW_S + 90)
            results += json.loads(out.strip().splitlines()[-1])
        assert len(results) == OBSERVERS
        worst_rate, worst_gap, worst_at, worst = 1e9, 0.0, 0.0, None
        for r in results:
            assert not r["closed"], f"an observer that reads was disconnected: {r['why']}"
            a = [0.0] + r["arrivals"]
            rate = (len(a) - 1) / WINDOW_S
            gap, at = max((y - x, x) for x, y in zip(a, a[1:]))
            if gap > worst_gap:
                worst_at, worst = at, r
            worst_rate, worst_gap = min(worst_rate, rate), max(worst_gap, gap)
        print(diagnose(worst, worst_at, worst_gap))
        rates = sorted(len(r["arrivals"]) / WINDOW_S for r in results)
        print(f"{OBSERVERS} observers: worst status rate {worst_rate:.1f} Hz, worst gap {worst_gap * 1000:.0f} ms; "
              f"median rate {rates[len(rates) // 2]:.1f} Hz; the worst gap began {worst_at:.2f} s into the window; "
              f"observers with a gap over 200 ms: {sum(1 for r in results if max(y - x for x, y in zip([0.0] + r['arrivals'], r['arrivals'])) > 0.2)}")
        assert worst_rate >= MIN_HZ, f"an observer got status at {worst_rate:.1f} Hz"
        assert worst_gap <= MAX_GAP_S, f"an observer saw a {worst_gap * 1000:.0f} ms gap in status"
    finally:
        for w in workers:
            if w.poll() is None:
                w.kill()
                w.wait()
        assert s.stop() == 0, s.output()


if __name__ == "__main__" and len(sys.argv) == 4 and sys.argv[1] == "worker":
    # The load generators run at the pendant's (this test's) priority. They used to yield
    # (nice 10), but then the pendant's bursts starved them: the worst gaps were their own
    # (their event loop 70-190 ms late while the gateway had built every status on time,
    # 20-40 ms apart), and the test measured the clients. At nice 0 their loop lags a few
    # ms and a gap is the gateway's (see diagnose()).
    os.nice(int(os.environ.get("SAFESTATE_LOAD_NICE", "0")))
    import uvloop  # noqa: PLC0415
    uvloop.run(worker_main(sys.argv[2], int(sys.argv[3])))
