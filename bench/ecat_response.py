#!/usr/bin/env python3
"""Response time of every safety function on the wire (issue 21 item 4, SPEC §13).

The whole cell over EtherCAT: `safestate ecat-sim` (the EMULATED segment) and `safestate run
--fieldbus ethercat --safety FILE` on the two ends of a veth pair in a network namespace of
this script's own, a fresh pair of processes per function. Each function is triggered as
rta/src/measure.cpp triggers it in-process: input contacts through the emulator's control
socket (channel a, channel b 5 ms later), drive faults of the scenario format (`fault drive 1
runaway` from rest, `fault contact N`), and for the limits a bench safety configuration with
the limit under test just beside the pose (the same file for `run --safety`). The emulator
times it, per exchange, with its own clock and exchange counter (`time STOP from=WHAT`, then
`status` -> `wire_timing`, sim/ecat/src/wire_timing.cpp); this script only waits for the
figures.

Configuration: examples/safety/collaborative.json (fields, PFL) with SSM off (on only for its
own row: the emulated segment's distance sensor, a subdevice of its own, carries the
separation) and without the brake-test schedule (nobody tested the brakes of a cell started a
second ago); per function the one limit under test changed. The
computed worst case is `safestate rta --json --bus-config hal/ethercat/default-bus.json
--safety` of that same file.

A measurement, not a test: it asserts nothing, but a function whose run did not do what it
needs (the cell did not arm, another alarm stopped the arm first, no figure within 10 s) is
recorded as not measured, with why. Needs a network namespace (as root `unshare -n`, else an
unprivileged user namespace, `unshare -rn`, where the kernel allows them) and, for the bus as
shipped (FIELDBUS_LOST after 3 stale cycles), real-time scheduling of the master and the
emulator: tried here as an unprivileged user (2026-11-27), the namespace and the veth pair came
up, but without SCHED_FIFO the master lost the bus at boot ("FIELDBUS_LOST after 3 stale cycles,
3.2 ms after the last answered frame") on this shared 2-core VM: root (or CAP_SYS_NICE /
RLIMIT_RTPRIO) is still what a run needs, for the scheduling, not for the namespace.

  .venv/bin/python bench/ecat_response.py --bin build/bin/safestate --json build/bench/ecat_response.json
"""
import argparse
import asyncio
import copy
import datetime
import json
import math
import os
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from ecat_reaction import PIN, Control, Pendant, free_port, wait_http  # noqa: E402

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), ".."))
BASE = os.path.join(ROOT, "examples", "safety", "collaborative.json")
BUS = os.path.join(ROOT, "hal", "ethercat", "default-bus.json")
SECOND_CHANNEL_S = 0.005  # channel b after channel a, well within discrepancy_ms (50)
KBESIDE = 1.2             # planning margins from the pose (rta/src/measure.cpp kBeside)
JOINT_MARGIN_RAD = math.radians(1.0)  # motion::kJointMarginRad
ZONE_MARGIN_MM = 10.0                 # motion::kZoneMarginMm
ORIENT_MARGIN_RAD = math.radians(1.0)  # motion::kOrientationMarginRad
BENCH_JOINT_SPEED_DEG_S = 60.0        # rta/src/measure.cpp kBenchJointSpeedRadS
BENCH_TCP_SPEED_MM_S = 300.0          # rta/src/measure.cpp kBenchTcpSpeedMmS
T1_LIMIT_MM_S = 250.0                 # core::Config::t1_speed_limit_mm_s
F_QS_HAND_N = 140.0                   # core::body_region(hand).f_qs_n

# id, the alarm that must be the function's own, the stop (wire_timing's STOP)
FUNCTIONS = [
    ("estop", "ESTOP_PRESSED", "cat0"),
    ("guard", "PROTECTIVE_STOP", "cat1"),
    ("enable", None, "cat1"),
    ("t1_speed", "T1_SPEED_EXCEEDED", "cat0"),
    ("joint_range", "JOINT_LIMIT", "cat0"),
    ("joint_speed", "SPEED_LIMIT", "cat0"),
    ("tcp_speed", "SPEED_LIMIT", "cat0"),
    ("reduced_speed", "REDUCED_SPEED", "reduce"),
    ("zones", "ZONE_VIOLATION", "cat0"),
    ("orientation", "ORIENTATION_LIMIT", "cat0"),
    ("field_outer", "REDUCED_SPEED", "reduce"),
    ("field_inner", "PERSON_IN_FIELD", "cat2"),
    ("ssm", None, "cat2"),
    ("collision", "COLLISION", "cat2"),
    ("bus_loss", None, "cat0"),
]
NOT_ON_THE_WIRE = {
    "bus_loss": "not timed per exchange: on the wire a bus loss is the exchanges stopping (bench/ecat_loss.py times "
                "the lockout from the last answered frame, docs/performance.md)",
}


def base_config():
    c = json.load(open(BASE))
    c.pop("brake_test", None)
    c["collaborative"]["ssm"]["enabled"] = False
    c["name"] = "rta wire bench: collaborative.json, SSM off"
    return c


def protective_distance(c, v):
    """SPEC §11 S_p for the robot at `v` mm/s (core::ssm_protective_distance_mm, v_h for d > 500)."""
    p = c["collaborative"]["ssm"]
    t_r, a = p["reaction_ms"] / 1000.0, p["decel_mm_s2"]
    t_s = v / a
    return p["human_speed_mm_s"] * (t_r + t_s) + v * t_r + v * t_s / 2 + p["intrusion_mm"] + p["uncertainty_mm"]


SSM_FAR_MM = 5000  # where the person stands before it steps in (v_allowed above every limit)


def bench_config(fid, home, pose):
    """The configuration of one function and what it says about it (`how` of the table)."""
    c = base_config()
    radius = c["tool"]["radius_mm"]
    if fid == "ssm":
        c["collaborative"]["ssm"]["enabled"] = True
        c["name"] = "rta wire bench: collaborative.json"
        sp = protective_distance(c, c["tcp_max_speed_mm_s"])
        return c, f"S_p {sp:.0f} mm (at the TCP limit {c['tcp_max_speed_mm_s']:g} mm/s)", f"separation<{sp:.0f}"
    if fid == "joint_range":
        mx = home[0] + KBESIDE * JOINT_MARGIN_RAD
        c["joints"][0]["max_deg"] = math.degrees(mx)
        return c, f"axis 1's max {math.degrees(mx - home[0]):.3g} deg beside it", f"joint.1>{mx:.9g}"
    if fid == "joint_speed":
        c["joints"][0]["max_speed_deg_s"] = BENCH_JOINT_SPEED_DEG_S
        return c, f"axis 1's max speed {BENCH_JOINT_SPEED_DEG_S:g} deg/s", \
            f"speed.1>{math.radians(BENCH_JOINT_SPEED_DEG_S):.9g}"
    if fid == "tcp_speed":
        c["tcp_max_speed_mm_s"] = BENCH_TCP_SPEED_MM_S
        c["reduced"]["tcp_max_speed_mm_s"] = min(c["reduced"]["tcp_max_speed_mm_s"], BENCH_TCP_SPEED_MM_S)
        return c, f"TCP max speed {BENCH_TCP_SPEED_MM_S:g} mm/s", f"tcp_speed>{BENCH_TCP_SPEED_MM_S:g}"
    if fid == "zones":
        # A keep_out box on the side axis 1 turns the TCP towards (+y at home), its face
        # KBESIDE zone margins from the tool sphere: crossed when the sphere touches it.
        p = pose["tcp_mm"]
        gap = KBESIDE * ZONE_MARGIN_MM
        face = p[1] + radius + gap
        c["zones"].append({"name": "rta-bench", "kind": "keep_out", "min_mm": [p[0] - 100, face, p[2] - 100],
                           "max_mm": [p[0] + 100, face + 100, p[2] + 100]})
        return c, f"a keep_out box {gap:g} mm beside the tool sphere", f"tcp.y>{face - radius:.3f}"
    if fid == "orientation":
        dev = KBESIDE * ORIENT_MARGIN_RAD
        c["orientation"] = {"axis": pose["tool_z"], "max_deviation_deg": math.degrees(dev)}
        return c, f"the tool axis allowed {math.degrees(dev):.3g} deg about its pose", f"tilt>{dev:.9g}"
    return c, "", None


class Cell:
    """ecat-sim on `ecs` and, once started, `safestate run --fieldbus ethercat` on `ecm`."""

    def __init__(self, a, d):
        self.a, self.d, self.procs = a, d, []
        self.ctl_path = os.path.join(d, "ctl.sock")
        if os.path.exists(self.ctl_path):
            os.unlink(self.ctl_path)
        self.spawn("sim", [a.bin, "ecat-sim", "--ifname", "ecs", "--control", self.ctl_path, "--cpu", PIN])
        for _ in range(200):
            if os.path.exists(self.ctl_path):
                break
            time.sleep(0.05)
        self.ctl = Control(self.ctl_path)

    def spawn(self, tag, cmd):
        log = os.path.join(self.d, tag + ".log")
        self.procs.append(subprocess.Popen(cmd, stdout=open(log, "w"), stderr=subprocess.STDOUT, cwd=self.d))
        return log

    def run(self, safety):
        self.port = free_port()
        log = self.spawn("run", [self.a.bin, "run", "--fieldbus", "ethercat", "--channels", "1", "--ifname", "ecm", "--cpu", PIN,
                                 "--ecat-sim-control", self.ctl_path, "--port", str(self.port), "--no-opcua",
                                 "--db", os.path.join(self.d, "ev.db"), "--safety", safety])
        wait_http(self.port, self.procs[-1], log)

    def close(self):
        for p in reversed(self.procs):
            p.terminate()
            try:
                p.wait(timeout=10)
            except subprocess.TimeoutExpired:
                p.kill()
        db = os.path.join(self.d, "ev.db")
        for f in (db, db + "-wal", db + "-shm"):
            if os.path.exists(f):
                os.unlink(f)


def axis1_speed(ctl, dt=0.02):
    q0, t0 = ctl.status()["joints"][0], time.monotonic()
    time.sleep(dt)
    q1, t1 = ctl.status()["joints"][0], time.monotonic()
    return abs(q1 - q0) / (t1 - t0)


async def command(p, cmd, **kw):
    p.seq += 1
    await p.ws.send(json.dumps({"type": "command", "seq": p.seq, "cmd": cmd, **kw}))
    end = time.monotonic() + 5
    while time.monotonic() < end:
        m = await p.recv(5)
        if m.get("type") in ("reply", "error") and m.get("seq") == p.seq:
            return m.get("result", m.get("code"))
    raise RuntimeError(f"no reply to {cmd}")


async def arm(p, ctl, mode):
    """Reset and validate the bench configuration in T1 (SPEC §10: only in a manual mode, with
    its checksum as the pendant shows it), then power in `mode` (T1: enabling device held)."""
    await p.state("ESTOP_RESET_NEEDED", 20)
    ctl.ok("in mode=T1")
    await asyncio.sleep(0.05)
    if await command(p, "reset") != "OK":
        raise RuntimeError(f"reset refused in {p.status.get('state')} (alarms {p.status.get('alarms')})")
    await p.state("IDLE")
    code = p.status.get("safety", {}).get("checksum")
    r = await command(p, "validate_config", code=code)
    if r != "OK":
        raise RuntimeError(f"validate_config {code} answered {r}")
    if mode == "AUTO":
        ctl.ok("in mode=AUTO")
    else:
        ctl.ok("in enable=centre")
    await asyncio.sleep(0.05)
    r = await command(p, "servo_on")
    if r != "OK":
        raise RuntimeError(f"servo_on answered {r} in {p.status.get('state')} (alarms {p.status.get('alarms')})")
    await p.state("OPERATIONAL")


async def running(p, ctl):
    """The demo program in AUTO until axis 1 turns faster than 1 rad/s (measure.cpp running())."""
    r = await command(p, "start")
    if r != "OK":
        raise RuntimeError(f"start answered {r}")
    end = time.monotonic() + 15
    while time.monotonic() < end:
        await p.recv(1)
        if axis1_speed(ctl) > 1.0:
            return
    raise RuntimeError("the demo program never turned axis 1 at 1 rad/s")


async def jogging(p, stop):
    """Hold-to-run: the jog command again every 40 ms until `stop` is set."""
    while not stop.is_set():
        p.seq += 1
        await p.ws.send(json.dumps({"type": "command", "seq": p.seq, "cmd": "jog", "axis": 1, "dir": "+",
                                    "speed": 100}))
        await asyncio.sleep(0.04)  # the replies are read by whoever waits (one reader per socket)


async def two_channels(ctl, a, b):
    ctl.ok(f"in {a}=0")
    await asyncio.sleep(SECOND_CHANNEL_S)
    ctl.ok(f"in {b}=0")


async def wait_figures(p, ctl, timeout=10.0):
    """Until the emulator has the safe state (or saw the arm stopped before the trigger); the
    alarms the pendant saw meanwhile (some last only while their condition does)."""
    alarms = set()
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        w = ctl.status()["wire_timing"]
        if w.get("safe") is not None or w.get("early_exchange") is not None:
            break
        try:
            await p.recv(0.02)
        except asyncio.TimeoutError:
            pass
        alarms |= set(p.status.get("alarms", []))
    for _ in range(5):
        try:
            await p.recv(0.1)
        except asyncio.TimeoutError:
            pass
        alarms |= set(p.status.get("alarms", []))
    return ctl.status()["wire_timing"], alarms


async def one(cell, fid, stop, frm, ssm_params=None):
    """Arms the cell, the measurement and the trigger; the emulator's figures and the alarms."""
    from websockets.asyncio.client import connect

    ctl = cell.ctl
    async with connect(f"ws://127.0.0.1:{cell.port}/ws", max_queue=None) as ws:
        await ws.send(json.dumps({"type": "hello", "role": "pendant", "client": "ecat response bench"}))
        p = Pendant(ws)
        mode = "T1" if fid in ("enable", "t1_speed") else "AUTO"
        await arm(p, ctl, mode)
        jog_stop = asyncio.Event()
        jog = None
        if fid in ("estop", "guard", "reduced_speed", "field_outer", "field_inner", "collision", "ssm"):
            await running(p, ctl)
            how = "AUTO, demo program at speed: "
        elif fid == "enable":
            jog = asyncio.create_task(jogging(p, jog_stop))
            await asyncio.sleep(0.3)
            how = "T1, axis 1 jogged at 100 %: "
        else:
            await asyncio.sleep(0.3)  # settled: held at the home pose
            how = ("T1" if mode == "T1" else "AUTO") + ", held at home, "
        ctl.ok(f"time {stop} from={frm}")
        if fid in ("estop", "guard", "reduced_speed"):
            ch = {"estop": "estop", "guard": "gate", "reduced_speed": "reduced"}[fid]
            await two_channels(ctl, ch + ".a", ch + ".b")
            how += f"{ch}.a opens, {ch}.b 5 ms later"
        elif fid in ("field_outer", "field_inner"):
            f = fid.replace("_", ".")
            await two_channels(ctl, f + ".a", f + ".b")
            how = "AUTO, collaborative on, demo program at speed: " + f"{f}.a interrupted, .b 5 ms later"
        elif fid == "enable":
            await two_channels(ctl, "enable.a", "enable.b")
            how += "enable.a released, enable.b 5 ms later"
        elif fid == "ssm":
            ssm = ssm_params
            near = ssm["intrusion_mm"] + ssm["uncertainty_mm"]
            ctl.ok(f"in separation_mm={near:g}")
            how = (f"AUTO, SSM on, demo program at speed, the person at {SSM_FAR_MM} mm: the distance sensor's reading "
                   f"falls to C + Z = {near:g} mm (v_allowed 0), counted from the exchange carrying it below the "
                   f"protective distance ({frm.split('<')[1]} mm, S_p at the TCP limit); timed as the function's own "
                   "reaction, the motion layer's hold (reaction: the commanded speed falls; safe: the targets still, "
                   "held 10 exchanges). The computed row is the monitor behind it (SEPARATION_VIOLATED, Cat 0 after "
                   "T_r, for a drive that does not follow), which a healthy arm does not reach: no alarm")
        elif fid == "collision":
            ctl.ok(f"fault contact {2 * F_QS_HAND_N:g}")
            how = f"AUTO, pfl on, demo program at speed: a contact of 2 x F_qs ({2 * F_QS_HAND_N:g} N) against the TCP"
        else:
            axis = 5 if fid == "orientation" else 1
            ctl.ok(f"fault drive {axis} runaway")
            how += f"drive {axis} runs away from rest"
        w, alarms = await wait_figures(p, ctl)
        jog_stop.set()
        if jog is not None:
            await jog
        return w, alarms, how


def computed(a, safety):
    out = subprocess.run([a.bin, "rta", "--json", "--bus-config", BUS, "--safety", safety], check=True,
                         stdout=subprocess.PIPE, text=True, cwd=ROOT).stdout
    return {f["id"]: f for f in json.loads(out)["functions"]}


CROSS_WHAT = {
    "t1_speed": "counted from the exchange carrying a point (TCP, link origins) over 250 mm/s",
    "joint_range": "counted from the exchange carrying its position past the max",
    "joint_speed": "counted from the exchange carrying its speed over it",
    "tcp_speed": "counted from the exchange carrying a TCP speed over it (the core's kinematics)",
    "zones": "counted from the exchange carrying a TCP whose sphere touches it",
    "orientation": "counted from the exchange carrying a tool axis outside the cone",
}


def inside(a):
    rows = []
    with tempfile.TemporaryDirectory(prefix="ssresp-") as d:
        for dev in (["link", "add", "ecm", "type", "veth", "peer", "name", "ecs"], ["link", "set", "dev", "ecm", "up"],
                    ["link", "set", "dev", "ecs", "up"], ["link", "set", "dev", "lo", "up"]):
            subprocess.run(["ip", *dev], check=True)
        for fid, alarm, stop in FUNCTIONS:
            if a.only and fid not in a.only:
                continue
            row = {"id": fid, "stop": stop, "measured": False}
            cell = Cell(a, d)
            try:
                c = base_config()
                cell.ctl.ok(f"tool {c['tool']['payload_kg']} {' '.join(str(x) for x in c['tool']['tcp_mm'])}")
                st = cell.ctl.status()
                home, pose = st["joints"], st["wire_timing"]
                cfg, limit_how, cross = bench_config(fid, home, pose)
                safety = os.path.join(d, f"safety-{fid}.json")
                json.dump(cfg, open(safety, "w"), indent=1)
                row["computed"] = computed(a, safety)[fid]
                if fid in NOT_ON_THE_WIRE:
                    row["how"] = NOT_ON_THE_WIRE[fid]
                    rows.append(row)
                    continue
                if fid == "t1_speed":
                    cross = f"point_speed>{T1_LIMIT_MM_S:g}"
                frm = cross or ("fault" if fid == "collision" else "input")
                if stop == "reduce":
                    stop = f"reduce={cfg['reduced']['tcp_max_speed_mm_s'] if fid == 'reduced_speed' else cfg['collaborative']['reduced_speed_mm_s']:g}"
                if fid == "ssm":  # a valid reading, far: SSM keeps every limit until the person steps in
                    cell.ctl.ok(f"in separation_mm={SSM_FAR_MM}")
                cell.run(safety)
                w, alarms, how = asyncio.run(one(cell, fid, stop, frm, cfg["collaborative"]["ssm"]))
                if limit_how and fid != "ssm":
                    how = how.replace("held at home, ", f"held at home, {limit_how}: ")
                if fid in CROSS_WHAT:
                    how += "; " + CROSS_WHAT[fid]
                row.update(how=how, wire=w, alarms=sorted(alarms), time=f"time {stop} from={frm}")
                if w.get("early_exchange") is not None and w.get("start_exchange") is None:
                    row["why"] = f"stopped (by {', '.join(sorted(alarms)) or '?'}) before the limit was crossed"
                elif w.get("reaction") is None or w.get("safe") is None:
                    row["why"] = f"no {'reaction' if w.get('reaction') is None else 'safe state'} within 10 s: {w}"
                elif alarm is not None and alarm not in alarms:
                    row["why"] = f"not the function's own alarm {alarm}: {sorted(alarms)}"
                else:
                    row["measured"] = True
                    row["alarm"] = alarm or ""
            except (RuntimeError, SystemExit, OSError, asyncio.TimeoutError, subprocess.CalledProcessError) as e:
                row["why"] = f"setup failed: {str(e)[:300]}"
                log = os.path.join(d, "run.log")
                if os.path.exists(log):  # what the master said about it
                    tail = [l for l in open(log).read().splitlines() if l.strip()][-3:]
                    row["why"] += " (run.log: " + " / ".join(tail) + ")"
            finally:
                cell.close()
            rows.append(row)
            w = row.get("wire") or {}
            print(f"{fid:14s} {'measured' if row['measured'] else 'NOT measured: ' + row.get('why', row.get('how', ''))}"
                  + (f": reaction {w['reaction']['cycles']} exchange(s) {w['reaction']['us']} us, safe "
                     f"{w['safe']['cycles']} exchange(s) {w['safe']['us']} us; computed "
                     f"{row['computed']['reaction_cycles']} / {row['computed']['total_us'] / 1000:.1f} ms"
                     if row["measured"] else ""), flush=True)
    res = {"date": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
           "namespace": "unshare -n (root)" if os.geteuid() == 0 else "unshare -rn (unprivileged user namespace)",
           "base": os.path.relpath(BASE, ROOT), "functions": rows}
    if a.json:
        with open(a.json, "w") as f:
            json.dump(res, f, indent=1)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--bin", default=os.environ.get("SAFESTATE_BIN", "build/bin/safestate"))
    ap.add_argument("--json", help="write the figures to this file")
    ap.add_argument("--only", nargs="*", help="function ids (default: all)")
    ap.add_argument("--inside", action="store_true", help=argparse.SUPPRESS)
    a = ap.parse_args()
    a.bin = os.path.abspath(a.bin)
    if a.json:
        a.json = os.path.abspath(a.json)
    if a.inside:
        return inside(a)
    # A network namespace of our own: as root one without a user namespace (the real-time
    # threads keep CAP_SYS_NICE), else an unprivileged user namespace where the kernel allows it.
    ns = ["unshare", "-n"] if os.geteuid() == 0 else ["unshare", "-rn"]
    cmd = [*ns, sys.executable, os.path.abspath(__file__), "--inside", "--bin", a.bin]
    if a.json:
        cmd += ["--json", a.json]
    if a.only:
        cmd += ["--only", *a.only]
    return subprocess.run(cmd).returncode


if __name__ == "__main__":
    sys.exit(main())
