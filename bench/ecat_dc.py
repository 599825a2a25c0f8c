#!/usr/bin/env python3
"""Distributed-clock sync error over EtherCAT (issue 22 item 1).

The whole cell: `safestate ecat-sim` (the EMULATED segment, its ESCs' clocks drifting by their
default ppm) and `safestate run --fieldbus ethercat` (1 ms cycle, the bus configuration as
shipped: SYNC0 on the six drives, 500 us after the cycle's start) on the two ends of a veth
pair in a network namespace this script creates and removes. Once the cell is in
ESTOP_RESET_NEEDED and the clocks have had 2 s to settle, the emulator's DC figures are reset
(`dc reset`) and read after `--seconds`: per drive, the sync error (its system time minus the
reference clock's at the same instant, sampled at every process-data frame) p99 and max, and
how the set-points met SYNC0 (taken, replaced before a SYNC0, SYNC0s without a new one, the
least time a frame arrived before the SYNC0 that took it).

What it shows: that the master's drift compensation (the FRMW of every exchange) keeps the
emulated clocks in step. The emulated clocks have no jitter, temperature or timestamp noise
of their own; a physical segment's figure depends on its ESCs and cabling. A measurement, not
a test: it asserts nothing. Needs root.

  sudo .venv/bin/python bench/ecat_dc.py --bin build/bin/safestate --seconds 60
"""
import json
import os
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from common import namespace_bench  # noqa: E402
from ecat_loss import Cell  # noqa: E402
from ecat_reaction import Control  # noqa: E402


def inside(a):
    with tempfile.TemporaryDirectory(prefix="ssdc-") as d:
        c = Cell(a, d)
        try:
            ctl = Control(c.ctl_path)
            time.sleep(2.0)
            ctl.ok("dc reset")
            time.sleep(a.seconds)
            st = ctl.status()["dc"]
        finally:
            c.close()
    drives = [i for i, on in enumerate(st["sync0_active"]) if on]
    if not drives:
        raise SystemExit(f"no drive has SYNC0 active: {st}")
    per = [st["stats"][i] for i in drives]
    res = {"seconds": a.seconds, "drives": len(drives), "reference": st["reference"],
           "samples": min(s["samples"] for s in per),
           "p99_ns": max(s["p99_ns"] for s in per), "max_ns": max(s["max_ns"] for s in per),
           "per_drive": [{"position": i + 1, **st["stats"][i]} for i in drives],
           "latched": sum(s["latched"] for s in per), "overwritten": sum(s["overwritten"] for s in per),
           "missed": sum(s["missed"] for s in per), "min_lead_us": min(s["min_lead_ns"] for s in per) / 1000.0,
           "drift_ppm": st["drift_ppm"]}
    print(f"sync error over {a.seconds} s, {len(drives)} drives, {res['samples']} samples each: p99 {res['p99_ns']} ns, "
          f"max {res['max_ns']} ns (worst drive); set-points taken by SYNC0 {res['latched']}, replaced before a "
          f"SYNC0 {res['overwritten']}, SYNC0s without a new one {res['missed']}, least lead {res['min_lead_us']:.1f} us")
    if a.json:
        with open(a.json, "w") as f:
            json.dump(res, f)


def main():
    return namespace_bench(__doc__, "ecat_dc", "ssdc", __file__, "seconds", 60, 3600, inside)

if __name__ == "__main__":
    sys.exit(main())
