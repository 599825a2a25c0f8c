#!/usr/bin/env python3
"""SPEC §14, issue 36 item 7: the fault-injection campaign, two channels against one.

Runs `safestate faults --json` (10,000 injections, seed 1) with two channels and with one, and
writes
  - the section "## Fault injection (SPEC §14): two channels against one" of docs/performance.md
    (replaced in place, or added before "## Footprint"; never hand-typed figures);
  - build/bench/faults.json: the raw figures (`--render` rewrites the section from it).
Called by `make bench` (bench/run.py); alone: `python3 bench/faults.py` (about a minute on two
cores). The campaign runs on the SIMULATED cell in replay (faults/campaign.hpp says how each
injection is classified); its figures are the design's, measured, not a certified DC.
"""
import datetime
import json
import os
import sys
import time

from common import BIN, OUT, ROOT, machine, run, write_section  # bench/common.py

DOC = os.path.join(ROOT, "docs", "performance.md")
TITLE = "## Fault injection (SPEC §14): two channels against one"
SEED = 1
INJECTIONS = 10000


def measure():
    d = {"runs": {}}
    for ch in (2, 1):
        t0 = time.monotonic()
        out = run([os.path.join(BIN, "safestate"), "faults", "--seed", str(SEED), "--injections", str(INJECTIONS),
                   "--channels", str(ch), "--json"])
        r = json.loads(out)
        r["wall_s"] = time.monotonic() - t0
        d["runs"][str(ch)] = r
    d["date"] = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    d["machine"] = machine()
    return d


def section(d):
    two, one = d["runs"]["2"], d["runs"]["1"]
    L = [TITLE, "",
         f"`safestate faults --seed {SEED} --injections {INJECTIONS}` on the simulated cell (replay), "
         f"{d['date']}, {d['machine']}. Each injection: one single fault (a channel stalled or crashed, a "
         "channel reading one contact wrong, digests corrupted, dropped or repeated, a contactor welded, a "
         "load-side encoder stuck, off or drifting, or — 70 % of them — one random bit of one channel's "
         "supervisor) at a random moment of one of four situations in turn, then after 300 ms each demand of "
         "that situation on a copy, each against its fault-free twin: safe within the twin's time plus "
         "`cross_check_cycles`. The demands, where they are made, and the safety function that answers each "
         "in the fault-free cell (asserted by test_faults):", ""]
    L += ["| demand | situation | answered by (fault-free) | fault-free reaction (cycles) | pairs safe, two channels "
          "| pairs safe, one channel |", "|---|---|---|---:|---:|---:|"]
    by_name = {x["name"]: x for x in one["demands"]}
    for x in two["demands"]:
        o = by_name.get(x["name"], {"safe": 0, "pairs": 0})
        L.append(f"| {x['name']} | {x['situation']} | {x['answered_by'] or 'its own stop (no alarm)'} | "
                 f"{x['reaction_cycles']} | {x['safe']} of {x['pairs']} | {o['safe']} of {o['pairs']} |")
    L += ["", "Classes: faults/campaign.hpp; [docs/two-channels.md](two-channels.md).", "",
         "| | two channels | one channel |", "|---|---:|---:|"]

    def row(name, key, fmt=str):
        L.append(f"| {name} | {fmt(two[key])} | {fmt(one[key])} |")
    row("injections", "injections")
    row("detected (a diagnostic lockout named it)", "detected")
    row("masked (no effect on the safety outputs)", "masked")
    row("fail-safe (outputs only towards safe, unnamed)", "failsafe")
    row("crashed (the channel's program failed)", "crashed")
    row("**dangerous, undetected**", "dangerous")
    row("**diagnostic coverage** (ISO 13849-1: ≥ 90 % medium, ≥ 99 % high)", "dc", lambda v: f"{100 * v:.2f} %")
    L.append(f"| (fault, demand) pairs safe in time | {two['pairs_safe']} of {two['pairs']} | "
             f"{one['pairs_safe']} of {one['pairs']} |")
    L.append(f"| fault to naming lockout, p50 / max (cycles of 1 ms) | {two['to_lockout_cycles']['p50']} / "
             f"{two['to_lockout_cycles']['max']} | {one['to_lockout_cycles']['p50']} / {one['to_lockout_cycles']['max']} |")
    L.append(f"| campaign wall time (s, two processes at once) | {two['wall_s']:.0f} | {one['wall_s']:.0f} |")
    L += ["", "By fault class (two channels / one channel: detected, masked, dangerous):", "",
          "| fault class | injected | two channels | one channel |", "|---|---:|---|---|"]
    by1 = {c["name"]: c for c in one["classes"]}
    for c in two["classes"]:
        o = by1.get(c["name"], {"detected": 0, "masked": 0, "dangerous": 0, "failsafe": 0})
        L.append(f"| {c['name']} | {c['injected']} | {c['detected']} / {c['masked']} / {c['dangerous']} | "
                 f"{o['detected']} / {o['masked']} / {o['dangerous']} |")
    L += ["", "Reading: with two channels every dangerous fault of the list is named and every demand stays safe; "
          "with one, a stalled controller takes every safety function away unnoticed, and a welded contactor lets an E-stop "
          "leave the arm powered (named by external device monitoring only afterwards). Most "
          "bit flips in a supervisor change nothing within the window (bytes of monitors not in use, values "
          "rewritten every cycle): masked, not counted in the coverage. What the campaign does not cover "
          "(the bus master, the plant, the host, two processes): docs/two-channels.md.", ""]
    return "\n".join(L) + "\n"


def write_doc(d):
    write_section(DOC, TITLE, section(d))
    print(f"bench: fault-injection section of {os.path.relpath(DOC, ROOT)} written")


def main():
    path = os.path.join(OUT, "faults.json")
    if sys.argv[1:] == ["--render"]:
        write_doc(json.load(open(path)))
        return
    os.makedirs(OUT, exist_ok=True)
    d = measure()
    with open(path, "w") as f:
        json.dump(d, f, indent=1)
    write_doc(d)


if __name__ == "__main__":
    main()
