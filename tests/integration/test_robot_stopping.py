"""Issue 38 item 5: `safestate rta` and the stopping-data bench on another arm than the built-in
IRB 120: example-robot-data's UR5 (the test venv, requirements-robots.txt).

- `safestate rta --robot UR5 --safety` with tool.payload_kg 3 of robot.rated_payload_kg 5 gives a
  Cat 0 stop term from the UR5's payload fraction (0.6), not the IRB 120's (3 kg of 3 kg = 1.0).
- `safestate safety check` judges tool.payload_kg by the levels of the arm's rated payload, and on
  another arm says that the measured data (the IRB 120's) do not apply rather than compare them.
- `bench/stopping.py --robot UR5 --short` (bench_stopping, 100 % speed and payload, 6 runs) runs on
  the UR5 and gives other figures than on the IRB 120.

How the figures are judged plausible (no figure is hard-coded): each run must follow the
simulated plant's own physics, from the description the test reads itself:
  - constant deceleration: the axis travel equals v0 x t / 2 within 5 % + 1 cycle;
  - Cat 0 braking is kBrakeStopDecelFactor (2) x the axis' acceleration limit (its URDF velocity /
    0.25 s, docs/robot.md) / (1 + 0.5 x payload fraction), so the stop time is v0 / that within
    one cycle + 2 %;
  - the rta's Cat 0 term is the same law from the velocity limit: qd_max / (2 x qdd_max / (1 +
    0.5 x fraction)) rounded up to cycles, with the fraction of the arm's own rated payload.
"""
import json
import math
import os
import subprocess
import sys
import sysconfig
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
BIN = Path(os.environ.get("SAFESTATE_BIN", ROOT / "build" / "bin" / "safestate"))
BENCH_DIR = Path(os.environ.get("BENCH_BIN_DIR", BIN.parent))
IRB120 = ROOT / "examples" / "robots" / "abb_irb120.urdf"
ACCEL_TIME_S = 0.25         # docs/robot.md: each axis reaches its speed limit in 0.25 s [ASM]
BRAKE_FACTOR = 2.0          # sim/plant.hpp kBrakeStopDecelFactor
PAYLOAD_RATIO = 0.5         # sim/plant.hpp kPayloadInertiaRatio
CYCLE_S = 1e-3


def ur5():
    p = (Path(sysconfig.get_paths()["purelib"]) / "cmeel.prefix" / "share" / "example-robot-data" / "robots" /
         "ur_description" / "urdf" / "ur5_robot.urdf")
    assert p.is_file(), "example-robot-data missing: pip install -r tests/integration/requirements-robots.txt"
    return p


def velocity_limits(urdf):
    """The chain's six revolute joints' velocity limits (rad/s), in chain order (both arms list them so)."""
    root = ET.parse(urdf).getroot()
    v = [float(j.find("limit").get("velocity")) for j in root.findall("joint") if j.get("type") in ("revolute", "continuous")]
    assert len(v) == 6, v
    return v


def config(tmp_path, name, payload_kg, rated_kg=None):
    c = json.loads((ROOT / "examples" / "safety" / "cell.json").read_text())
    for k in ("joints", "zones", "orientation"):  # the IRB 120's cell; the arm's own ranges instead
        c.pop(k, None)
    c["tool"]["payload_kg"] = payload_kg
    if rated_kg is not None:
        c["robot"] = {"rated_payload_kg": rated_kg}
    p = tmp_path / f"{name}.json"
    p.write_text(json.dumps(c))
    return p


def cat0_term_cycles(robot, cfg):
    out = subprocess.run([str(BIN), "rta", "--robot", str(robot), "--safety", str(cfg), "--json"], capture_output=True,
                         text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    d = json.loads(out.stdout)
    estop = next(f for f in d["functions"] if f["id"] == "estop")
    term = next(t for t in estop["terms"] if t["name"].startswith("Cat 0 stop"))
    return term["us"] // 1000, term["basis"]


def expected_cat0_cycles(urdf, fraction):
    worst = 0
    for qd in velocity_limits(urdf):
        per_cycle = BRAKE_FACTOR * (qd / ACCEL_TIME_S) / (1 + PAYLOAD_RATIO * fraction) * CYCLE_S
        worst = max(worst, math.ceil(qd / per_cycle - 1e-4))
    return worst


def test_rta_cat0_stop_uses_the_arms_rated_payload(tmp_path):
    robot = ur5()
    irb_cycles, irb_basis = cat0_term_cycles(IRB120, config(tmp_path, "irb", 3.0))
    ur_cycles, ur_basis = cat0_term_cycles(robot, config(tmp_path, "ur5", 3.0, rated_kg=5.0))
    assert irb_cycles == expected_cat0_cycles(IRB120, 3.0 / 3.0), irb_basis
    assert ur_cycles == expected_cat0_cycles(robot, 3.0 / 5.0), ur_basis
    assert ur_cycles < irb_cycles, "3 kg is 60 % of the UR5's 5 kg, all of the IRB 120's 3 kg"
    assert "of rated 5.00, robot ur5" in ur_basis, ur_basis
    # The same 5 kg on the UR5 is its full rated payload: the IRB 120's fraction, the same law.
    full, _ = cat0_term_cycles(robot, config(tmp_path, "ur5-full", 5.0, rated_kg=5.0))
    assert full == expected_cat0_cycles(robot, 1.0)


def safety_check(cfg, *args):
    out = subprocess.run([str(BIN), "safety", "check", *args, str(cfg)], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stdout + out.stderr
    return [l.strip() for l in out.stdout.splitlines() if l.strip().startswith("warning:")]


def test_safety_check_stopping_levels_follow_the_rated_payload(tmp_path):
    # The IRB 120 declared for 1.5 kg, carrying 1 kg: 67 % of its rated payload, above the 66 %
    # level (0.99 kg), so judged by the 100 % figures (Cat 1: 357 ms, stopping_data.hpp) and a
    # 330 ms limit is too short. Against the 3 kg the 66 % level (1.98 kg) would pass it.
    c = json.loads((ROOT / "examples" / "safety" / "cell.json").read_text())
    c["tool"]["payload_kg"] = 1.0
    c["robot"] = {"rated_payload_kg": 1.5}
    c["stop"]["max_time_ms"] = 330
    p = tmp_path / "irb-1.5.json"
    p.write_text(json.dumps(c))
    w = safety_check(p)
    assert len(w) == 1 and "stop.max_time_ms: 330 ms" in w[0] and "payload 100 %" in w[0], w
    # The UR5: the figures are the IRB 120's, so not compared; said once, naming the arm.
    w = safety_check(config(tmp_path, "ur5", 3.0, rated_kg=5.0), "--robot", str(ur5()))
    assert len(w) == 1 and "not checked against measured stopping data" in w[0] and "robot ur5" in w[0], w


def bench(tmp_path, name, *args):
    out = tmp_path / f"{name}.json"
    r = subprocess.run([sys.executable, str(ROOT / "bench" / "stopping.py"), "--short", "--json", str(out), *args],
                       capture_output=True, text=True, timeout=120,
                       env={**os.environ, "PYTHONPATH": str(ROOT / "bench")})
    assert r.returncode == 0, r.stdout + r.stderr
    assert "| 100 % |" in r.stdout, r.stdout
    return json.loads(out.read_text()), r.stdout


def plausible(d, urdf):
    qd = velocity_limits(urdf)
    assert len(d["runs"]) == 6 and all(r["ok"] for r in d["runs"]), d["runs"]
    for r in d["runs"]:
        i = r["axis"] - 1
        v0 = r["v0_deg_s"]
        t = r["stop_cycles"] * CYCLE_S
        assert 0 < v0 <= math.degrees(qd[i]) * 1.001, (r["axis"], v0, qd[i])
        # Constant deceleration: travel v0 t / 2 (the count is up to one cycle long).
        assert abs(r["distance_deg"] - v0 * t / 2) <= 0.05 * r["distance_deg"] + v0 * CYCLE_S, r
        if r["cat"] == 0:
            decel = math.degrees(BRAKE_FACTOR * qd[i] / ACCEL_TIME_S) / (1 + PAYLOAD_RATIO * r["payload"])
            assert abs(t - v0 / decel) <= 0.02 * t + 2 * CYCLE_S, (r, v0 / decel)
        else:  # Cat 1: a ramp, slower than the brakes, within stop.max_time_ms
            assert t <= d["max_stop_ms"] * 1e-3, r
    return {(r["axis"], r["cat"]): (r["stop_cycles"], r["distance_deg"]) for r in d["runs"]}


def test_stopping_bench_short_on_the_ur5_differs_from_the_irb120(tmp_path):
    robot = ur5()
    written = [ROOT / "docs" / "stopping-data.md", ROOT / "safety" / "include" / "safestate" / "safety" / "stopping_data.hpp"]
    before = [p.stat().st_mtime_ns for p in written]
    irb, _ = bench(tmp_path, "irb")
    ur, text = bench(tmp_path, "ur5", "--robot", str(robot), "--rated-payload-kg", "5")
    assert irb["builtin"] is True and irb["robot"] == "abb_irb120_3_58"
    assert ur["builtin"] is False and ur["robot"] == "ur5" and ur["payload_rated_kg"] == 5.0
    assert "stopping data of ur5" in text
    a = plausible(irb, IRB120)
    b = plausible(ur, robot)
    # The UR5's axes are slower (180 deg/s against the IRB 120's 250): shorter stops and travel.
    differ = [k for k in a if a[k] != b[k]]
    assert len(differ) == 6, (a, b)
    assert ur["summary"] != irb["summary"]
    # The documents and the checker's header hold the IRB 120's full table: untouched by either.
    assert [p.stat().st_mtime_ns for p in written] == before


if __name__ == "__main__":
    sys.exit(pytest.main([__file__, "-q"]))
