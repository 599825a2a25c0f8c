#!/usr/bin/env python3
"""SPEC §13, ISO 10218-1 Annex B: stopping time and distance of axes 1-3 on the SIMULATED cell.

Runs build/bin/bench_stopping (Cat 0 and Cat 1, 33/66/100 % speed, 33/66/100 % payload) and writes
  - docs/stopping-data.md: the tables, how they were made, the ISO 13855 minimum distance S = K*T + C;
  - docs/stopping/axisN-catC.svg: stopping time and distance against speed, one line per payload
    (drawn by this script, no hand edits);
  - safety/include/safestate/safety/stopping_data.hpp: the figures `safestate safety check` compares
    the configuration with (generated, never typed by hand).
Called by `make bench` (bench/run.py); alone: `python3 bench/stopping.py` (a few seconds).

Another arm (issue 38): `python3 bench/stopping.py --robot FILE.urdf [--rated-payload-kg KG]
[--short] [--json OUT]` measures it the same way and prints the per-payload summary (what
`safestate safety check` would compare) without writing the documents or the header, which hold
the built-in IRB 120's figures. --short: 100 % speed and payload only (a test's run).
"""
import argparse
import datetime
import json
import os

from common import BIN, ROOT, machine, run  # bench/common.py

DOC = os.path.join(ROOT, "docs", "stopping-data.md")
SVG_DIR = os.path.join(ROOT, "docs", "stopping")
HEADER = os.path.join(ROOT, "safety", "include", "safestate", "safety", "stopping_data.hpp")
K_MM_S = 1600.0          # ISO 13855 approach speed used here (the brief's K)
CURTAIN_D_MM = 30.0      # assumed guard: a light curtain of 30 mm resolution
C_MM = 8.0 * (CURTAIN_D_MM - 14.0)  # ISO 13855 intrusion distance for d <= 40 mm
COLORS = {0.33: "#1b9e77", 0.66: "#d95f02", 1.0: "#7570b3"}


def panel(x0, y0, w, h, runs, key, label, ymax):
    """One chart: speed % on x, `key` on y, a polyline per payload."""
    out = [f'<rect x="{x0}" y="{y0}" width="{w}" height="{h}" fill="none" stroke="#444"/>',
           f'<text x="{x0 + w / 2}" y="{y0 + h + 34}" text-anchor="middle" font-size="12">speed (% of the axis limit)</text>',
           f'<text x="{x0 - 44}" y="{y0 + h / 2}" text-anchor="middle" font-size="12" '
           f'transform="rotate(-90 {x0 - 44} {y0 + h / 2})">{label}</text>']
    for t in range(0, 6):
        v = ymax * t / 5
        y = y0 + h - h * t / 5
        out.append(f'<line x1="{x0 - 4}" y1="{y:.1f}" x2="{x0}" y2="{y:.1f}" stroke="#444"/>')
        out.append(f'<text x="{x0 - 6}" y="{y + 4:.1f}" text-anchor="end" font-size="10">{v:.0f}</text>')
    for s in (0, 33, 66, 100):
        x = x0 + w * s / 100
        out.append(f'<line x1="{x:.1f}" y1="{y0 + h}" x2="{x:.1f}" y2="{y0 + h + 4}" stroke="#444"/>')
        out.append(f'<text x="{x:.1f}" y="{y0 + h + 16}" text-anchor="middle" font-size="10">{s}</text>')
    for p, col in COLORS.items():
        pts = [(r["speed"], r[key]) for r in runs if abs(r["payload"] - p) < 1e-3]
        pts.sort()
        xy = [(x0 + w * s, y0 + h - h * v / ymax) for s, v in [(0.0, 0.0)] + pts]
        out.append(f'<polyline fill="none" stroke="{col}" stroke-width="2" points="'
                   + " ".join(f"{a:.1f},{b:.1f}" for a, b in xy) + '"/>')
        for a, b in xy[1:]:
            out.append(f'<circle cx="{a:.1f}" cy="{b:.1f}" r="3" fill="{col}"/>')
    return out


def svg(axis, cat, runs):
    w, h = 300, 220
    tmax = max(r["stop_ms"] for r in runs) * 1.1
    dmax = max(r["distance_deg"] for r in runs) * 1.1
    out = ['<svg xmlns="http://www.w3.org/2000/svg" width="760" height="330" font-family="sans-serif">',
           '<rect width="100%" height="100%" fill="white"/>',
           f'<text x="380" y="22" text-anchor="middle" font-size="15">Axis {axis}, Cat {cat} stop: '
           'SIMULATED cell (stands in for the real arm)</text>']
    out += panel(70, 40, w, h, runs, "stop_ms", "stopping time (ms)", tmax)
    out += panel(440, 40, w, h, runs, "distance_deg", "stopping distance (deg)", dmax)
    for n, (p, col) in enumerate(COLORS.items()):
        out.append(f'<rect x="{250 + n * 110}" y="306" width="14" height="4" fill="{col}"/>')
        out.append(f'<text x="{268 + n * 110}" y="312" font-size="11">payload {round(p * 100)} %</text>')
    out.append("</svg>")
    return "\n".join(out) + "\n"


def summary(d):
    """Per payload level measured: the longest Cat 1 and Cat 0 stops, the lowest TCP deceleration."""
    per_level = []
    for p in sorted({r["payload"] for r in d["runs"]}):
        rs = [r for r in d["runs"] if abs(r["payload"] - p) < 1e-3]
        c1 = max((r for r in rs if r["cat"] == 1), key=lambda r: r["stop_ms"])
        c0 = max((r for r in rs if r["cat"] == 0), key=lambda r: r["stop_ms"])
        dec = min((r for r in rs if r["tcp0_mm_s"] > 100.0), key=lambda r: r["tcp_decel_mm_s2"])
        per_level.append({"payload": p, "cat1": c1, "cat0": c0, "decel": dec})
    return per_level


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--robot", help="another arm's URDF (not written to the documents)")
    ap.add_argument("--base")
    ap.add_argument("--flange")
    ap.add_argument("--rated-payload-kg", type=float, help="its rated payload (the label of the payload fractions)")
    ap.add_argument("--short", action="store_true", help="100 %% speed and payload only")
    ap.add_argument("--json", help="also write the runs and the summary here")
    a = ap.parse_args()
    cmd = [os.path.join(BIN, "bench_stopping")]
    for flag, v in (("--robot", a.robot), ("--base", a.base), ("--flange", a.flange)):
        if v:
            cmd += [flag, v]
    if a.rated_payload_kg is not None:
        cmd += ["--rated-payload-kg", str(a.rated_payload_kg)]
    if a.short:
        cmd.append("--short")
    d = json.loads(run(cmd))
    cyc = d["cycle_us"]
    bad = [r for r in d["runs"] if not r["ok"]]
    if bad:
        raise SystemExit(f"bench: stopping: {len(bad)} run(s) failed: " + "; ".join(
            f"axis {r['axis']} Cat {r['cat']} {r['speed']}/{r['payload']}: {r['why']}" for r in bad))
    for r in d["runs"]:
        r["stop_ms"] = r["stop_cycles"] * cyc / 1000.0
        r["reaction_ms"] = r["reaction_cycles"] * cyc / 1000.0
        # The constant deceleration that stops the TCP within the measured distance (SSM's a).
        r["tcp_decel_mm_s2"] = r["tcp0_mm_s"] ** 2 / (2.0 * r["tcp_distance_mm"]) if r["tcp_distance_mm"] > 0 else 0.0
    if a.robot or a.short:  # not the built-in arm's full table: report only
        per_level = summary(d)
        rated = d["payload_rated_kg"]
        print(f"stopping data of {d['robot']} (SIMULATED cell; rated payload "
              f"{'%g kg' % rated if rated is not None else 'not given'}"
              f"{', short: 100 % speed only' if d['short'] else ''})")
        print("| payload | longest Cat 1 stop | longest Cat 0 stop | lowest TCP deceleration |")
        print("|---|---|---|---|")
        for lv in per_level:
            print(f"| {round(lv['payload'] * 100)} % | {lv['cat1']['stop_ms']:.0f} ms (axis {lv['cat1']['axis']}) | "
                  f"{lv['cat0']['stop_ms']:.0f} ms (axis {lv['cat0']['axis']}) | "
                  f"{lv['decel']['tcp_decel_mm_s2']:.0f} mm/s² (axis {lv['decel']['axis']}, Cat {lv['decel']['cat']}) |")
        if a.json:
            d["summary"] = [{"payload": lv["payload"], "cat1_stop_ms": lv["cat1"]["stop_ms"], "cat1_axis": lv["cat1"]["axis"],
                             "cat0_stop_ms": lv["cat0"]["stop_ms"], "cat0_axis": lv["cat0"]["axis"],
                             "tcp_decel_mm_s2": lv["decel"]["tcp_decel_mm_s2"]} for lv in per_level]
            with open(a.json, "w") as f:
                json.dump(d, f, indent=1)
        return
    rta = json.loads(run([os.path.join(BIN, "safestate"), "rta", "--json"]))
    guard = next(f for f in rta["functions"] if f["id"] == "guard")
    date = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    os.makedirs(SVG_DIR, exist_ok=True)
    for axis in (1, 2, 3):
        for cat in (0, 1):
            runs = [r for r in d["runs"] if r["axis"] == axis and r["cat"] == cat]
            with open(os.path.join(SVG_DIR, f"axis{axis}-cat{cat}.svg"), "w") as f:
                f.write(svg(axis, cat, runs))

    levels = [0.33, 0.66, 1.0]
    per_level = summary(d)
    reaction_ms = max(r["reaction_ms"] for r in d["runs"])
    worst1 = per_level[-1]["cat1"]
    t_ctrl_ms = guard["reaction_cycles"] * cyc / 1000.0
    t_s = (t_ctrl_ms + worst1["stop_ms"]) / 1000.0
    s_mm = K_MM_S * t_s + C_MM

    L = ["<!-- Generated by `make bench` (bench/stopping.py); do not edit: run it again. -->", "",
         "# Stopping time and distance (ISO 10218-1 Annex B, SPEC §13)", "",
         "**These figures come from the SIMULATED cell** (the real controller driving the simulated plant of",
         "sim/): they stand in for measurements on the real arm, which must be made there before a cell is",
         "signed off. They show what the controller adds and how the figures follow from the plant's model.", "",
         "## How these figures were made", "",
         "- Command: `make bench` (bench/run.py calls `bench/stopping.py`, which runs `build/bin/bench_stopping`);",
         "  alone: `python3 bench/stopping.py` (a few seconds).",
         f"- Date: {date}; machine: {machine()}. The figures are counted in cycles of the cell ({cyc} µs),",
         "  so they do not depend on the machine.",
         "- Each run: the arm at home, a one-waypoint program moving only the axis under test at 33/66/100 % of its",
         "  speed limit (the planner keeps 5 % below the limits, SPEC §10, and axis 2 at 100 % is held by the TCP",
         "  limit); once the axis runs steadily, the payload is applied and both channels of the E-stop (Cat 0)",
         "  or of the guard in AUTO (Cat 1) open together. Stopping time: cycles from that change until every axis",
         "  is below `standstill_rad_s`; distance: the axis' travel in that time (both up to one cycle",
         "  conservative). The built-in safety configuration (stop.max_time_ms "
         f"{d['max_stop_ms']}).",
         "",
         "## Payload model (an assumption of the simulated cell)", "",
         f"ABB publishes no inertias. We assume that the rated payload ({d['payload_rated_kg']:.0f} kg, motion/robot.hpp) at",
         f"full extension makes the inertia each axis moves {1 + d['payload_inertia_ratio']:.1f} times the unloaded arm's",
         f"(sim/plant.hpp `kPayloadInertiaRatio` = {d['payload_inertia_ratio']}), so every deceleration the drives or the",
         f"brakes can give falls to 1 / (1 + {d['payload_inertia_ratio']} × fraction). \"Payload 33/66/100 %\" is that fraction",
         "of the rated payload, at full extension (Annex B's worst case). Without torque (Cat 0) the brakes stop an axis",
         f"at {d['brake_decel_factor']:.0f}× its acceleration limit (`kBrakeStopDecelFactor`); in Cat 1 the controller ramps",
         "at the unloaded limit and an axis that cannot follow gets the drive's own quick stop (CiA 402), which",
         "ramps at the loaded limit. The planner of the simulated cell does not know the payload: the run-up is",
         "the unloaded arm's and the payload acts from the stop on.", ""]
    for axis in (1, 2, 3):
        L += [f"## Axis {axis}", "",
              f"![axis {axis}, Cat 0](stopping/axis{axis}-cat0.svg) ![axis {axis}, Cat 1](stopping/axis{axis}-cat1.svg)", "",
              "| stop | speed | speed at the stop (deg/s) | payload 33 % | payload 66 % | payload 100 % |",
              "|---|---|---|---|---|---|"]
        for cat in (0, 1):
            for sp in levels:
                rs = sorted((r for r in d["runs"] if r["axis"] == axis and r["cat"] == cat and abs(r["speed"] - sp) < 1e-3),
                            key=lambda r: r["payload"])
                cells = " | ".join(f"{r['stop_ms']:.0f} ms, {r['distance_deg']:.2f}°" for r in rs)
                L.append(f"| Cat {cat} | {round(sp * 100)} % | {rs[0]['v0_deg_s']:.0f} | {cells} |")
        L.append("")
    L += ["## Minimum distance of the guard (ISO 13855)", "",
          "S = K × T + C with K = 1600 mm/s (the approach speed of ISO 13855 for S above 500 mm, as asked here),",
          f"T = the controller's reaction to the guard ({guard['reaction_cycles']} cycle(s), `safestate rta`, built-in",
          f"configuration: {t_ctrl_ms:.0f} ms) + the longest Cat 1 stopping time above (axis {worst1['axis']}, 100 % speed,",
          f"100 % payload: {worst1['stop_ms']:.0f} ms) = {t_s * 1000:.0f} ms, and C = 8 × (d − 14) = {C_MM:.0f} mm for the",
          f"**assumed guard: a light curtain of d = {CURTAIN_D_MM:.0f} mm resolution** (ISO 13855, d ≤ 40 mm). The",
          "curtain's own response time is not included: add it to T for the device used.", "",
          f"**S = 1600 mm/s × {t_s:.3f} s + {C_MM:.0f} mm = {s_mm:.0f} mm.**", "",
          "## What `safestate safety check` compares", "",
          "safety/include/safestate/safety/stopping_data.hpp (generated by this script) holds, per payload level, the",
          "longest Cat 1 stopping time and the lowest TCP deceleration measured (v² / (2 × the TCP's stopping",
          "distance)), and the longest reaction (change → the axis slows). `safestate safety check FILE` warns when",
          "`stop.max_time_ms` is below the Cat 1 stopping time, `collaborative.ssm.decel_mm_s2` above the deceleration,",
          "or `collaborative.ssm.reaction_ms` below the reaction, at the first level at or above `tool.payload_kg`.", "",
          "| payload | longest Cat 1 stop | longest Cat 0 stop | lowest TCP deceleration |", "|---|---|---|---|"]
    for lv in per_level:
        L.append(f"| {round(lv['payload'] * 100)} % | {lv['cat1']['stop_ms']:.0f} ms (axis {lv['cat1']['axis']}) | "
                 f"{lv['cat0']['stop_ms']:.0f} ms (axis {lv['cat0']['axis']}) | {lv['decel']['tcp_decel_mm_s2']:.0f} mm/s² "
                 f"(axis {lv['decel']['axis']}, Cat {lv['decel']['cat']}) |")
    L.append("")
    with open(DOC, "w") as f:
        f.write("\n".join(L))

    H = ["// Generated by bench/stopping.py (`make bench`) from build/bin/bench_stopping on the SIMULATED cell",
         f"// ({date}); do not edit: run it again. docs/stopping-data.md says how the figures were made.",
         "// `safestate safety check` warns when a configuration promises a faster stop than these.",
         "#pragma once", "", "#include <array>", "", "namespace safestate::safety::stopping {", "",
         "struct Level {",
         "  double payload_fraction;  // of the rated payload (motion::kRatedPayloadKg)",
         "  double cat1_stop_ms;      // longest Cat 1 stopping time, axes 1-3, up to 100 % speed",
         "  int cat1_axis;",
         "  double tcp_decel_mm_s2;   // lowest TCP deceleration, v^2 / (2 x stopping distance)",
         "};", "",
         f"inline constexpr const char* kSource = \"bench/stopping.py, simulated cell, {date}\";",
         f"inline constexpr double kReactionMs = {reaction_ms:.3f};  // longest: change -> the axis slows",
         "inline constexpr std::array<Level, 3> kLevels{{"]
    for lv in per_level:
        H.append(f"    {{{lv['payload']:.2f}, {lv['cat1']['stop_ms']:.3f}, {lv['cat1']['axis']}, "
                 f"{lv['decel']['tcp_decel_mm_s2']:.1f}}},")
    H += ["}};", "", "}  // namespace safestate::safety::stopping", ""]
    with open(HEADER, "w") as f:
        f.write("\n".join(H))
    print(f"bench: wrote {os.path.relpath(DOC, ROOT)}, docs/stopping/*.svg, {os.path.relpath(HEADER, ROOT)}; "
          f"S = {s_mm:.0f} mm")


if __name__ == "__main__":
    main()
