#!/usr/bin/env python3
"""Cycle cost of two trees side by side (issue 35: a refactoring may cost at most +5 %).

For each tree (a checkout with its own build/): valgrind's callgrind on bench_cycle
(instructions per cycle of the supervisor alone and of the full cell, exact and repeatable),
and tools/scripts/embedded_bench.sh (Cortex-M4 instructions per scan cycle in QEMU, the
configurations it measures). Prints a Markdown table with the change in per cent.

usage: bench/compare_cost.py --before TREE --after TREE [--cycles N] [--json]
"""
import argparse
import json
import os
import re
import subprocess
import sys
import tempfile

SERIES = ["supervisor-typical", "supervisor-worst", "full-typical"]


def callgrind(tree, what, cycles):
    binary = os.path.join(tree, "build", "bin", "bench_cycle")
    with tempfile.NamedTemporaryFile(suffix=".out") as f:
        subprocess.run(["valgrind", "--tool=callgrind", "--instr-atstart=no", f"--callgrind-out-file={f.name}",
                        binary, "callgrind", what, "--cycles", str(cycles)],
                       check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        total = 0
        for line in open(f.name):
            m = re.match(r"^(?:summary|totals):\s+(\d+)", line)
            if m:
                total = max(total, int(m.group(1)))  # callgrind writes "summary: 0" before the totals
        if total:
            return total / cycles
    raise SystemExit(f"compare_cost: no total in callgrind's output for {what} in {tree}")


def m4(tree):
    out = subprocess.run(["tools/scripts/embedded_bench.sh"], cwd=tree, check=True, capture_output=True, text=True)
    return json.loads(out.stdout)


def flat(d, prefix=""):
    for k, v in d.items():
        if isinstance(v, dict):
            yield from flat(v, f"{prefix}{k}.")
        elif isinstance(v, (int, float)) and not isinstance(v, bool):
            yield f"{prefix}{k}", v


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--before", required=True)
    ap.add_argument("--after", required=True)
    ap.add_argument("--cycles", type=int, default=100000)
    ap.add_argument("--no-m4", action="store_true", help="callgrind only (no arm-none-eabi / QEMU)")
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args()
    rows = []
    for what in SERIES:
        b, f = callgrind(a.before, what, a.cycles), callgrind(a.after, what, a.cycles)
        rows.append((f"callgrind {what}", b, f))
    if not a.no_m4:
        mb, mf = dict(flat(m4(a.before))), dict(flat(m4(a.after)))
        names = {"baseline": "monitors not configured", "zones0": "no zone", "zones16": "16 zones and a cone",
                 "zones16_all": "16 zones, every zone tested"}
        for k, name in names.items():
            if k in mb and k in mf:
                rows.append((f"Cortex-M4 instructions / cycle, {name}", mb[k], mf[k]))
    if a.json:
        print(json.dumps([{"series": s, "before": b, "after": f} for s, b, f in rows], indent=1))
        return 0
    print("| series | before | after | change |")
    print("|---|---|---|---|")
    for s, b, f in rows:
        print(f"| {s} | {b:,.0f} | {f:,.0f} | {100.0 * (f - b) / b:+.1f} % |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
