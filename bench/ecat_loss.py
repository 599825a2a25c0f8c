#!/usr/bin/env python3
"""Bus-loss detection and output drop over EtherCAT, several trials each (issue 22 items 2, 3).

The whole cell: `safestate ecat-sim` (the EMULATED segment) and `safestate run --fieldbus
ethercat` (1 ms cycle, the bus configuration as shipped: FIELDBUS_LOST after 3 stale cycles,
process-data watchdogs at 10 cycles) on the two ends of a veth pair in a network namespace
this script creates and removes. Each trial starts a fresh cell:

- bus loss: the emulator is killed (SIGKILL) once the cell is in ESTOP_RESET_NEEDED; the
  master's log says how many stale cycles and how long after the last answered frame it
  locked out (timed by the master on its monotonic clock); `/metrics` gives the overruns
  from the kill on (none is the goal while the bus is gone) and, for comparison, in as
  many cycles just before it with the bus up.
- output drop: the cell is armed (reset, servo on: contactor bit and every controlword
  0x000F on the wire), then the master is killed with SIGKILL; the emulator times, from the
  last exchange it answered, when its DO terminal dropped the contactor and the drives lost
  their enable by their own process-data watchdog (`status` -> `output_drop`).

Prints the figures; `--json F` writes them. A measurement, not a test: it asserts nothing,
but stops with an error if the cell does not do what a trial needs. Needs root.

  sudo .venv/bin/python bench/ecat_loss.py --bin build/bin/safestate --trials 5
"""
import asyncio
import json
import os
import re
import signal
import subprocess
import sys
import tempfile
import time
import urllib.request

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from common import namespace_bench  # noqa: E402
from ecat_reaction import PIN, Control, Pendant, arm, figures, free_port, wait_http  # noqa: E402

LOST = re.compile(r"FIELDBUS_LOST after (\d+) stale cycles, ([0-9.]+) ms after the last answered frame")


def metric(port, name):
    text = urllib.request.urlopen(f"http://127.0.0.1:{port}/metrics", timeout=2).read().decode()
    for line in text.splitlines():
        if line.startswith(name + " "):
            return float(line.split()[1])
    raise SystemExit(f"/metrics has no {name}")


def status(port):
    return json.loads(urllib.request.urlopen(f"http://127.0.0.1:{port}/api/status", timeout=2).read())


def wait(cond, what, timeout):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        v = cond()
        if v:
            return v
        time.sleep(0.02)
    raise SystemExit("timed out waiting for " + what)


class Cell:
    def __init__(self, a, d):
        self.ctl_path = os.path.join(d, "ctl.sock")
        self.run_log = os.path.join(d, "run.log")
        self.sim = subprocess.Popen([a.bin, "ecat-sim", "--ifname", "ecs", "--control", self.ctl_path, "--cpu", PIN],
                                    stdout=subprocess.DEVNULL, stderr=subprocess.STDOUT)
        wait(lambda: os.path.exists(self.ctl_path), "the emulator's control socket", 10)
        self.port = free_port()
        self.run = subprocess.Popen([a.bin, "run", "--fieldbus", "ethercat", "--channels", "1", "--ifname", "ecm", "--cpu", PIN, "--ecat-sim-control",
                                     self.ctl_path, "--port", str(self.port), "--no-opcua", "--db",
                                     os.path.join(d, "ev.db")],
                                    stdout=open(self.run_log, "w"), stderr=subprocess.STDOUT, cwd=d,
                                    start_new_session=True)  # its gateway goes with it at the end
        wait_http(self.port, self.run, self.run_log)
        wait(lambda: status(self.port).get("state") == "ESTOP_RESET_NEEDED", "ESTOP_RESET_NEEDED", 20)

    def close(self):
        for p in (self.run, self.sim):
            if p.poll() is None:
                p.terminate()
                try:
                    p.wait(timeout=10)
                except subprocess.TimeoutExpired:
                    p.kill()
                    p.wait()
        try:  # a master killed with -9 leaves its gateway behind, in its session
            os.killpg(self.run.pid, signal.SIGTERM)
        except ProcessLookupError:
            pass


def bus_loss(a, d):
    c = Cell(a, d)
    try:
        # The same number of cycles with the bus up first: overruns the host causes anyway
        # (an ordinary process in a system call on the loop's CPU delays its wake-up on a
        # kernel that does not preempt kernel code), to set those after the kill against.
        before = metric(c.port, "safestate_overruns_total")
        cycles = metric(c.port, "safestate_cycles_total")
        wait(lambda: metric(c.port, "safestate_cycles_total") >= cycles + 500, "500 cycles with the bus", 10)
        overruns = metric(c.port, "safestate_overruns_total")
        c.sim.kill()
        c.sim.wait()
        m = wait(lambda: LOST.search(open(c.run_log).read()), "FIELDBUS_LOST in the master's log", 5)
        cycles = metric(c.port, "safestate_cycles_total")
        wait(lambda: metric(c.port, "safestate_cycles_total") >= cycles + 500, "500 cycles without the bus", 10)
        return {"stale_cycles": int(m.group(1)), "ms": float(m.group(2)), "overruns_before": overruns - before,
                "overruns": metric(c.port, "safestate_overruns_total") - overruns}
    finally:
        c.close()


async def armed(port):
    from websockets.asyncio.client import connect

    async with connect(f"ws://127.0.0.1:{port}/ws", max_queue=None) as ws:  # see tests/integration/ecat/pendant.py
        await ws.send(json.dumps({"type": "hello", "role": "pendant", "client": "ecat loss bench"}))
        await arm(Pendant(ws))


def output_drop(a, d):
    c = Cell(a, d)
    try:
        asyncio.run(armed(c.port))
        ctl = Control(c.ctl_path)
        w = ctl.status()
        if not (w["contactor"] and all(cw == 0x000F for cw in w["controlword"])):
            raise SystemExit(f"armed, but the outputs on the wire are not set: {w}")
        c.run.kill()
        c.run.wait()
        drop = wait(lambda: (lambda o: o if o["enable_us"] is not None and o["contactor_us"] is not None else None)(
            ctl.status()["output_drop"]), "the outputs dropping at the emulator", 5)
        return {"contactor_us": drop["contactor_us"], "enable_us": drop["enable_us"],
                "watchdog_us": ctl.status()["watchdog_us"][0]}
    finally:
        c.close()


def inside(a):
    losses, drops = [], []
    for i in range(a.trials):
        with tempfile.TemporaryDirectory(prefix="ssloss-") as d:
            r = bus_loss(a, d)
        losses.append(r)
        print(f"bus loss {i + 1}: FIELDBUS_LOST after {r['stale_cycles']} stale cycles, {r['ms']:.3f} ms after the "
              f"last answered frame; overruns from the kill on {r['overruns']:.0f} (in as many cycles before it, bus up: "
              f"{r['overruns_before']:.0f})", flush=True)
    for i in range(a.trials):
        with tempfile.TemporaryDirectory(prefix="ssloss-") as d:
            r = output_drop(a, d)
        drops.append(r)
        print(f"output drop {i + 1}: contactor {r['contactor_us']} us, enable {r['enable_us']} us after the last "
              f"exchange (watchdog {r['watchdog_us']} us)", flush=True)
    res = {"trials": a.trials,
           "loss_ms": figures([r["ms"] for r in losses]),
           "loss_stale_cycles": figures([r["stale_cycles"] for r in losses]),
           "loss_overruns": sum(r["overruns"] for r in losses),
           "loss_overruns_before": sum(r["overruns_before"] for r in losses),
           "drop_contactor_us": figures([r["contactor_us"] for r in drops]),
           "drop_enable_us": figures([r["enable_us"] for r in drops]),
           "watchdog_us": drops[0]["watchdog_us"]}
    print(f"bus loss, {a.trials} trials: {res['loss_ms']['min']:.3f}..{res['loss_ms']['max']:.3f} ms after the last "
          f"answered frame, overruns {res['loss_overruns']:.0f} (bus up, as many cycles: {res['loss_overruns_before']:.0f}); output drop: contactor "
          f"{res['drop_contactor_us']['min']}..{res['drop_contactor_us']['max']} us, enable "
          f"{res['drop_enable_us']['min']}..{res['drop_enable_us']['max']} us")
    if a.json:
        with open(a.json, "w") as f:
            json.dump(res, f)


def main():
    return namespace_bench(__doc__, "ecat_loss", "ssloss", __file__, "trials", 5, 1000, inside)

if __name__ == "__main__":
    sys.exit(main())
