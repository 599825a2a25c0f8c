#!/usr/bin/env python3
"""SPEC §14, issue 36 item 7: real-time faults of one channel's process, measured from outside.

Runs build/bin/bench_pair (the GCC and the Clang channel programs on the simulated world, the host
on a 1 ms clock, the robot powered; then SIGSTOP or SIGKILL of one channel, or a cycle overrun of
channel A: SIGSTOP and SIGCONT after 0.5..5 ms) and writes
  - the section "## Real-time faults of one channel (SPEC §14)" of docs/performance.md (replaced
    in place, or added before "## Footprint"; never hand-typed figures);
  - build/bench/pair_faults.json: the raw figures (`--render` rewrites the section from it).
Called by `make bench` (bench/run.py); alone: `python3 bench/pair_faults.py [TRIALS]` (20 trials per
kind by default, about four minutes).
"""
import datetime
import json
import os
import sys

from common import BIN, OUT, ROOT, machine, run, write_section  # bench/common.py

DOC = os.path.join(ROOT, "docs", "performance.md")
TITLE = "## Real-time faults of one channel (SPEC §14)"
SEED = 1


def measure(trials):
    out = run([os.path.join(BIN, "bench_pair"), os.path.join(BIN, "safestate-channel"),
               os.path.join(BIN, "safestate-channel-clang"), str(trials), str(SEED)])
    d = json.loads(out)
    d["date"] = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    d["machine"] = machine()
    return d


def cost_lines(d):
    """Issue 36 item 9: what the second channel and the cross-check cost on Linux."""
    s = d.get("steady")
    L = ["### What a channel costs (Linux)", ""]
    if s:
        def row(name, x):
            return f"| {name} | {x['p50']:.1f} | {x['p99']:.1f} | {x['p999']:.1f} | {x['max']:.1f} |"
        L += [f"The AUTO demo program for {s['cycles']} cycles on the {d['cycle_us']} us clock, each channel's own step "
              "(its controller cycle and its cross-check; the channel's clock, from taking the frame to its report) and "
              "the host's cycle (publish the frame, wait for both reports, combine the outputs), in microseconds:", "",
              "| | p50 | p99 | p99.9 | max |", "|---|---:|---:|---:|---:|",
              row("channel A (GCC), its step", s["a_us"]), row("channel B (Clang), its step", s["b_us"]),
              row("the host's cycle (both channels, in parallel on two CPUs)", s["host_us"]), ""]
    cc = d.get("crosscheck_ns", -1.0)
    if cc >= 0:
        L += [f"The cross-check alone (a digest made, sent, the partner's received and compared field by field): "
              f"{cc:.0f} ns per cycle on this machine, in a loop of a million. Its Cortex-M4 instructions: the section "
              "\"Cortex-M4 instructions per scan cycle\" above. One channel alone (`--channels 1`) runs the same "
              "controller cycle in the `safestate run` process: \"Scan cycle, cycle by cycle\" above (the full scan cycle).", ""]
    return L


def section(d):
    limit = d["cross_check_cycles"] + 1
    L = [TITLE, "",
         f"`bench/pair_faults.py` ({d['trials_per_kind']} trials per kind, seed {d['seed']}), {d['date']}, "
         f"{d['machine']}. The two channel programs (A: GCC, B: Clang) as processes of their own on the simulated "
         f"world, the host stepping them on a {d['cycle_us']} us clock as `safestate run` does, the robot powered; "
         "then, at a random phase of a cycle, a signal from outside: SIGSTOP (a hung processor), SIGKILL (a crashed "
         "one), or a cycle overrun of channel A (SIGSTOP, SIGCONT after the time given). Measured: how often the "
         "other channel named `CHANNEL_LOST`, and the host cycles (and microseconds from the signal) until the "
         "other channel's contactor bit was open — the power path is open then, K1 and K2 being in series. "
         f"Goal (issue 36): within `cross_check_cycles` + 1 = {limit} cycles.", "",
         "| fault | trials | CHANNEL_LOST | power path opened | cycles p50 / max | us p50 / max | within the goal |",
         "|---|---:|---:|---:|---:|---:|---|"]
    for k in d["kinds"]:
        opened = k["opened"]
        cyc = f"{k['cycles_p50']:.0f} / {k['cycles_max']:.0f}" if opened else "—"
        us = f"{k['us_p50']:.0f} / {k['us_max']:.0f}" if opened else "—"
        if opened:
            ok = "yes" if k["cycles_max"] <= limit else f"**no** (max {k['cycles_max']:.0f})"
        else:
            ok = "— (caught up: no lockout)" if k["lost"] == 0 else "**no** (lost, never opened)"
        L.append(f"| {k['kind']} | {k['trials']} | {k['lost']} | {opened} | {cyc} | {us} | {ok} |")
    L += ["", "Reading: a channel that stops or dies is found by the other within the cross-check's window "
          "and the power path opens in the cycle it decides, whichever channel it is. An overrun shorter "
          "than the window is ridden out (the late channel catches up on every frame it missed, in order: "
          "pair/shm.hpp); one longer is a lost channel. The overruns between those two are where a single "
          "late wake-up decides — docs/two-channels.md \"On a shared host\" says why this VM's scheduler "
          "makes them longer than a real controller's.", ""]
    L += cost_lines(d)
    return "\n".join(L) + "\n"


def write_doc(d):
    write_section(DOC, TITLE, section(d))
    print(f"bench: real-time channel faults section of {os.path.relpath(DOC, ROOT)} written")


def main():
    path = os.path.join(OUT, "pair_faults.json")
    if sys.argv[1:] == ["--render"]:
        write_doc(json.load(open(path)))
        return
    trials = int(sys.argv[1]) if sys.argv[1:] else 20
    os.makedirs(OUT, exist_ok=True)
    d = measure(trials)
    with open(path, "w") as f:
        json.dump(d, f, indent=1)
    write_doc(d)


if __name__ == "__main__":
    main()
