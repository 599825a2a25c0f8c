#!/usr/bin/env python3
"""Cycle cost of two trees side by side (issue 35: a refactoring may cost at most +5 %).

For each tree (a checkout with its own build/): valgrind's callgrind on bench_cycle
(instructions per cycle of the supervisor alone and of the full cell, exact and repeatable),
and tools/scripts/embedded_bench.sh (Cortex-M4 instructions per scan cycle in QEMU, the
configurations it measures). Prints a Markdown table with the change in per cent.

For a comparison across issues that add safety functions, `--new-work` names functions (regular
expressions over callgrind's function names) whose growth over the before tree is new work of
the safety functions, not cost of the shape: the table then has the after figure without that
growth as well (each named function's inclusive instructions per cycle after, minus before, never
below zero). The series "-limits" run with a safety configuration (bench::cost_limits()); a
tree from before the series existed gets them from a patch (bench/cost_series_621bd10.patch for
621bd10: `git apply` in that tree, then build bench_cycle).

usage: bench/compare_cost.py --before TREE --after TREE [--cycles N] [--new-work RE,...] [--json]
"""
import argparse
import json
import os
import re
import subprocess
import sys
import tempfile

SERIES = ["supervisor-typical", "supervisor-worst", "supervisor-limits", "full-typical", "full-limits"]


def callgrind(tree, what, cycles, functions=()):
    """Instructions per cycle of `what`, and each regex of `functions`: inclusive per cycle."""
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
        if not total:
            raise SystemExit(f"compare_cost: no total in callgrind's output for {what} in {tree}")
        inclusive = {}
        if functions:
            out = subprocess.run(["callgrind_annotate", "--inclusive=yes", "--threshold=100", f.name],
                                 check=True, capture_output=True, text=True).stdout
            for rx in functions:
                best = 0
                for line in out.splitlines():
                    # A function's own line ends with its object in brackets; call sites do not.
                    m = re.match(r"^\s*([\d,]+) \([^)]*\)\s+(.*) \[[^\]]*\]$", line)
                    if m and re.search(rx, m.group(2)):
                        best = max(best, int(m.group(1).replace(",", "")))
                inclusive[rx] = best / cycles
        return total / cycles, inclusive


def label(rx):
    """A function's name for the table: the regex up to its class or its parameter list."""
    return re.split(r"\\\(|::|\(", rx)[0]


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
    ap.add_argument("--new-work", default="",
                    help="comma-separated regexes of functions whose growth is new safety work (see above)")
    a = ap.parse_args()
    functions = [x for x in a.new_work.split(",") if x]
    rows = []
    for what in SERIES:
        (b, bi), (f, fi) = callgrind(a.before, what, a.cycles, functions), callgrind(a.after, what, a.cycles, functions)
        grown = {rx: max(0.0, fi[rx] - bi[rx]) for rx in functions}
        rows.append((f"callgrind {what}", b, f, f - sum(grown.values()) if functions else None, grown))
    if not a.no_m4:
        mb, mf = dict(flat(m4(a.before))), dict(flat(m4(a.after)))
        names = {"baseline": "monitors not configured", "zones0": "no zone", "zones16": "16 zones and a cone",
                 "zones16_all": "16 zones, every zone tested"}
        for k, name in names.items():
            if k in mb and k in mf:
                rows.append((f"Cortex-M4 instructions / cycle, {name}", mb[k], mf[k], None, {}))
    if a.json:
        print(json.dumps([{"series": s, "before": b, "after": f, "after_without_new_work": w, "new_work": g}
                          for s, b, f, w, g in rows], indent=1))
        return 0
    if functions:
        print("| series | before | after | change | new safety work (growth per function) | after without it | change |")
        print("|---|---|---|---|---|---|---|")
    else:
        print("| series | before | after | change |")
        print("|---|---|---|---|")
    for s, b, f, w, g in rows:
        line = f"| {s} | {b:,.0f} | {f:,.0f} | {100.0 * (f - b) / b:+.1f} % |"
        if functions:
            if w is None:
                line += " | | |"
            else:
                work = ", ".join(f"{label(rx)} +{v:,.0f}" for rx, v in g.items() if v >= 0.5) or "none"
                line += f" {work} | {w:,.0f} | {100.0 * (w - b) / b:+.1f} % |"
        print(line)
    return 0


if __name__ == "__main__":
    sys.exit(main())
