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

OBSERVERS = int(os.environ.get("SAFESTATE_LOAD_OBSERVERS", "500"))
WORKERS = 5
WINDOW_S = 10.0
MIN_HZ = 45.0
MAX_GAP_S = 0.250
BURSTS = 3
BURST = 2000

try:  # websockets >= 13
    from websockets.asyncio.client import connect as ws_connect
except ImportError:  # pragma: no cover
    from websockets import connect as ws_connect


# ---------------------------------------------------------------------------- worker
async def observer(url, ready, go, out):
    ws = await ws_connect(url, open_timeout=30, max_size=2 ** 22, ping_interval=None)
    await ws.send(json.dumps({"type": "hello", "role": "observer", "client": "load"}))
    async for raw in ws:
        if '"welcome"' in raw[:40]:
            break
        if '"error"' in raw[:40]:
            raise RuntimeError(f"hello refused: {raw}")
    ready()
    arrivals = []
    loop = asyncio.get_running_loop()
    closed = False
    try:
        async for raw in ws:
            if go.is_set() and raw.startswith('{"type":"status"'):
                now = loop.time()
                arrivals.append(now)
                if now - go.t0 > WINDOW_S:
                    break
    except Exception:  # noqa: BLE001 - a closed connection is a failure reported below
        closed = True
    out.append({"arrivals": [a - go.t0 for a in arrivals], "closed": closed})
    await ws.close()


async def worker_main(url, n):
    go = asyncio.Event()
    go.t0 = 0.0
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
    await asyncio.wait_for(asyncio.gather(*tasks), WINDOW_S + 60)
    print(json.dumps(out), flush=True)


# ---------------------------------------------------------------------------- test
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
            await p.close()
        run(main())

        results = []
        for w in workers:
            out, _ = w.communicate(timeout=WINDOW_S + 90)
            results += json.loads(out.strip().splitlines()[-1])
        assert len(results) == OBSERVERS
        worst_rate, worst_gap = 1e9, 0.0
        for r in results:
            assert not r["closed"], "an observer that reads was disconnected"
            a = [0.0] + r["arrivals"]
            rate = (len(a) - 1) / WINDOW_S
            gap = max(y - x for x, y in zip(a, a[1:]))
            worst_rate, worst_gap = min(worst_rate, rate), max(worst_gap, gap)
        print(f"500 observers: worst status rate {worst_rate:.1f} Hz, worst gap {worst_gap * 1000:.0f} ms")
        assert worst_rate >= MIN_HZ, f"an observer got status at {worst_rate:.1f} Hz"
        assert worst_gap <= MAX_GAP_S, f"an observer saw a {worst_gap * 1000:.0f} ms gap in status"
    finally:
        for w in workers:
            if w.poll() is None:
                w.kill()
                w.wait()
        assert s.stop() == 0, s.output()


if __name__ == "__main__" and len(sys.argv) == 4 and sys.argv[1] == "worker":
    asyncio.run(worker_main(sys.argv[2], int(sys.argv[3])))
