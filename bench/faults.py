#!/usr/bin/env python3
"""SPEC §14, issue 36 item 7: the fault-injection campaign, two channels against one.

Runs `safestate faults --json` (10,000 injections, seed 1) with two channels and with one, and
writes
  - the section "## Fault injection (SPEC §14): two channels against one" of docs/performance.md
    (replaced in place, or added before "## Footprint"; never hand-typed figures);
  - build/bench/faults.json: the raw figures (`--render` rewrites the section from it).
Called by `make bench` (bench/run.py); alone: `python3 bench/faults.py` (about three minutes on two
cores).

Issue 37 item 6: the same campaign with `--fieldbus ethercat` (the black channel in the simulated
world, and faults on its wire), two channels and one, writes the section "## Bus faults in the
fault campaign (issue 37)" and build/bench/bus_faults.json; `--bus` runs only that part. The campaign runs on the SIMULATED cell in replay (faults/campaign.hpp says how each
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
BUS_TITLE = "## Bus faults in the fault campaign (issue 37)"
SEED = 1
INJECTIONS = 10000


def measure(fieldbus=None):
    d = {"runs": {}}
    for ch in (2, 1):
        t0 = time.monotonic()
        extra = ["--fieldbus", fieldbus] if fieldbus else []
        out = run([os.path.join(BIN, "safestate"), "faults", "--seed", str(SEED), "--injections", str(INJECTIONS),
                   "--channels", str(ch), *extra, "--json"])
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


def bus_section(d):
    two, one = d["runs"]["2"], d["runs"]["1"]
    wd = two["watchdog_cycles"]
    L = [BUS_TITLE, "",
         f"`safestate faults --seed {SEED} --injections {INJECTIONS} --fieldbus ethercat` (and `--channels 1`), "
         f"{d['date']}, {d['machine']}. The warm cells carry the black channel of the shipped segment **in the "
         "simulated world** (sim/black_channel.hpp): the containers, each channel's ends and the sixteen devices' "
         "ends are the real code, the bus between them a byte copy in the process — no frames, no master, no wire "
         "timing (the wire is ecat-sim's to test). A quarter of the injections, drawn from a stream of their own, "
         "are single faults on that wire, in either direction, on a random connection at a random moment: a "
         "flipped bit, a container 2 to 9 cycles old replayed, two connections' containers swapped, a "
         "connection's container held 11 to 20 cycles (past the watchdog), another connection's container "
         "inserted; the others are the sim campaign's faults. Caught: `SAFETY_LINK_FAULT` named before the "
         "demands. Times in cycles of 1 ms from the injection to the safe output terminal's K1 or K2 open (the "
         "power path open: they are in series) and to both open, and from the last new valid container the "
         f"channel accepted on the faulted connection to K1 or K2 open (what the {wd}-cycle watchdog bounds). "
         "docs/black-channel.md, \"Bus faults in the campaign\", reads them.", "",
         "| bus fault | channels | injected | caught | dangerous | to SAFETY_LINK_FAULT, max | K1 or K2 open, "
         "p50 / max | from the last valid container, max | K1 and K2 open, p50 / max | errors named |",
         "|---|---:|---:|---:|---:|---:|---:|---:|---:|---|"]
    for ch, r in (("2", two), ("1", one)):
        for b in r["bus_faults"]:
            errors = ", ".join(f"{k} {v}" for k, v in sorted(b["errors"].items()))
            L.append(f"| {b['name']} | {ch} | {b['injected']} | {b['caught']} | {b['dangerous']} | "
                     f"{b['to_link_fault_cycles']['max']} | {b['to_power_open_cycles']['p50']} / "
                     f"{b['to_power_open_cycles']['max']} | {b['from_last_valid_to_power_open_cycles']['max']} | "
                     f"{b['to_both_open_cycles']['p50']} / {b['to_both_open_cycles']['max']} | {errors} |")
    L += ["", "The whole campaign with the black channel:", "",
          "| | two channels | one channel |", "|---|---:|---:|"]

    def row(name, key, fmt=str):
        L.append(f"| {name} | {fmt(two[key])} | {fmt(one[key])} |")
    row("injections", "injections")
    row("detected", "detected")
    row("masked", "masked")
    row("fail-safe", "failsafe")
    row("crashed", "crashed")
    row("**dangerous, undetected**", "dangerous")
    row("**diagnostic coverage**", "dc", lambda v: f"{100 * v:.2f} %")
    L.append(f"| (fault, demand) pairs safe in time | {two['pairs_safe']} of {two['pairs']} | "
             f"{one['pairs_safe']} of {one['pairs']} |")
    L.append(f"| campaign wall time (s, two processes at once) | {two['wall_s']:.0f} | {one['wall_s']:.0f} |")
    L += ["", "Reading: every bus fault is named, with either channel count, and the power path opens within the "
          "watchdog of the last valid container; from the injection a delay takes one cycle more (a container was "
          "already on its way: docs/black-channel.md). These totals are not the sim campaign's beside the bus "
          "faults: a quarter of the injections are bus faults, all detected, and with the black channel a hung "
          "channel stops refreshing its containers, so the output terminal's watchdog opens the power path "
          "even with one channel (a stalled channel is fail-safe here, dangerous in the sim campaign). What one "
          "channel still loses: the E-stop past a welded contactor (no second one), and the few faults of its own "
          "inputs and memory that only a partner would see (by class: build/bench/bus_faults.json).", ""]
    return "\n".join(L) + "\n"


def write_doc(d):
    write_section(DOC, TITLE, section(d))
    print(f"bench: fault-injection section of {os.path.relpath(DOC, ROOT)} written")


def write_bus_doc(d):
    write_section(DOC, BUS_TITLE, bus_section(d))
    print(f"bench: bus-fault section of {os.path.relpath(DOC, ROOT)} written")


def main():
    path = os.path.join(OUT, "faults.json")
    bus_path = os.path.join(OUT, "bus_faults.json")
    if sys.argv[1:] == ["--render"]:
        if os.path.exists(path):
            write_doc(json.load(open(path)))
        if os.path.exists(bus_path):
            write_bus_doc(json.load(open(bus_path)))
        return
    os.makedirs(OUT, exist_ok=True)
    if sys.argv[1:] != ["--bus"]:
        d = measure()
        with open(path, "w") as f:
            json.dump(d, f, indent=1)
        write_doc(d)
    b = measure("ethercat")
    with open(bus_path, "w") as f:
        json.dump(b, f, indent=1)
    write_bus_doc(b)


if __name__ == "__main__":
    main()
