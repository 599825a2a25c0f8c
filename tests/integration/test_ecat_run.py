"""`safestate run --fieldbus ethercat` end to end: the core on our ethercrab master, over
a veth pair in a network namespace this test creates and removes, against `safestate
ecat-sim` on the other end. Boot, arming, an E-stop on one channel seen on the wire, and
every way of losing the bus (a short working counter alone too), and a wrong identity
(product code or revision).

Run as root:  SAFESTATE_BIN=build/bin/safestate .venv/bin/python -m pytest tests/integration/test_ecat_run.py
"""

import functools
import json
import signal
import os
import socket
import subprocess
import sys
import tempfile
import time
import uuid
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
BIN = os.path.abspath(os.environ.get("SAFESTATE_BIN", str(ROOT / "build" / "bin" / "safestate")))
PENDANT = Path(__file__).resolve().parent / "ecat" / "pendant.py"

pytestmark = pytest.mark.skipif(os.geteuid() != 0, reason="needs root: network namespaces and raw sockets")

# The master's real-time loop and the emulated segment on one CPU (`--cpu` of both), as
# docs/ethercat.md ("Timing on a shared host") says to run them: each exchange then runs
# send -> emulator -> answer on one running CPU, without waking another. Left free, a
# wake-up on the other CPU waited for it to leave idle or kernel code (this VM's kernel
# does not preempt kernel code): up to 4.5 ms, stale cycles in a row on an idle host.
PIN = str(os.cpu_count() - 1)


def sh(*args, check=True):
    return subprocess.run(args, check=check, capture_output=True, text=True, timeout=30)


class Cell:
    """ecat-sim on `ecs`, `safestate run --fieldbus ethercat` on `ecm`, both in one namespace."""

    def __init__(self, sim_args=(), sim_late_s=0.0, run_args=(), bus=None, sim_lines=(), channels=1):
        self.ns = "ssrun-" + uuid.uuid4().hex[:8]
        # One channel unless a test says otherwise: these tests time one controller's
        # reactions on the wire; SPEC §14's pair (the default on the shipped segment) has its
        # own tests below (channels=None: the default).
        if channels is not None:
            run_args = (*run_args, "--channels", str(channels))
        self.tmp = tempfile.TemporaryDirectory(prefix="ssrun-")
        # The event log in memory: on this VM a synchronous disk write stalls the other CPU
        # too (`safestate rtbench` pinned to one CPU, a dsync dd on the other: woken up to 10 ms
        # late, 60 overruns in 20 s; without it 2.9 ms at most), longer than the drives'
        # 10-cycle process-data watchdog. These tests time the master, not the disk.
        self.shm = tempfile.TemporaryDirectory(prefix="ssrun-", dir="/dev/shm" if os.path.isdir("/dev/shm") else None)
        if bus:
            run_args = (*run_args, "--bus-config", bus_config(self.tmp.name, **bus))
            if "link_watchdog_ms" in bus:  # the safe devices must be parameterised the same
                sim_args = (*sim_args, "--link-watchdog-ms", str(bus["link_watchdog_ms"]))
        self.control = os.path.join(self.tmp.name, "ctl.sock")
        self.port = 18000 + (os.getpid() * 7 + int(uuid.uuid4().hex[:4], 16)) % 20000  # own namespace: no clash
        self.procs = []
        sh("ip", "netns", "add", self.ns)
        try:
            sh("ip", "-n", self.ns, "link", "add", "ecm", "type", "veth", "peer", "name", "ecs")
            for dev in ("ecm", "ecs", "lo"):
                sh("ip", "-n", self.ns, "link", "set", dev, "up")
            start_sim = lambda: self.spawn("sim", BIN, "ecat-sim", "--ifname", "ecs", "--control", self.control,
                                           "--cpu", PIN, *sim_args)
            if not sim_late_s:
                self.sim = start_sim()
                self.wait(lambda: os.path.exists(self.control), "ecat-sim control socket")
                for line in sim_lines:  # control lines before the master starts (a `freeze ... at-op`)
                    assert self.control_line(line) == "OK", line
            self.run = self.spawn("run", BIN, "run", "--fieldbus", "ethercat", "--ifname", "ecm", "--cpu", PIN,
                                  "--ecat-sim-control", self.control, "--port",
                                  str(self.port), "--db", os.path.join(self.shm.name, "ev.db"), "--static",
                                  self.tmp.name, *run_args)
            if sim_late_s:  # the segment powers up after the controller
                time.sleep(sim_late_s)
                self.sim = start_sim()
            self.wait(lambda: self.status() is not None, "safestate run serving /api/status", 30)
        except BaseException:
            self.close()
            raise

    def spawn(self, tag, *cmd):
        log = open(os.path.join(self.tmp.name, tag + ".log"), "w")
        p = subprocess.Popen(["ip", "netns", "exec", self.ns, *cmd], stdout=log, stderr=subprocess.STDOUT,
                             cwd=self.tmp.name)
        self.procs.append((p, log))
        return p

    def log(self, tag):
        return Path(self.tmp.name, tag + ".log").read_text()

    @staticmethod
    def wait(cond, what, timeout=15):
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if cond():
                return
            time.sleep(0.05)
        raise AssertionError("timed out waiting for " + what)

    def status(self):
        return self.api("status")

    def alarm(self, name):
        """The active alarm `name` as GET /api/alarms shows it (number, text, since ...)."""
        return next((a for a in self.api("alarms") or [] if a.get("name") == name), None)

    def get(self, path):
        r = subprocess.run(["ip", "netns", "exec", self.ns, sys.executable, "-c",
                            "import urllib.request,sys;"
                            f"print(urllib.request.urlopen('http://127.0.0.1:{self.port}{path}',timeout=2).read().decode())"],
                           capture_output=True, text=True, timeout=10)
        return r.stdout if r.returncode == 0 and r.stdout.strip() else None

    def api(self, what):
        text = self.get("/api/" + what)
        return json.loads(text) if text else None

    def metrics(self, *names):
        """Several values from one scrape of /metrics."""
        lines = (self.get("/metrics") or "").splitlines()
        return [next((float(l.split()[-1]) for l in lines if l.startswith(n + " ")), None) for n in names]

    def metric(self, name):
        for line in (self.get("/metrics") or "").splitlines():
            if line.startswith(name + " "):
                return float(line.split()[1])
        return None

    def wait_state(self, state, timeout=15):
        last = {}

        def ok():
            nonlocal last
            last = self.status() or {}
            return last.get("state") == state
        try:
            self.wait(ok, "state " + state, timeout)
        except AssertionError:
            raise AssertionError(f"expected {state}, last status {last}\nrun log:\n{self.log('run')}")
        return last

    def control_line(self, line):
        with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as s:
            s.settimeout(5)
            s.connect(self.control)
            s.sendall((line + "\n").encode())
            return s.recv(65536).decode().strip()

    def wire(self):
        return json.loads(self.control_line("status"))

    def pendant(self, cmds, want):
        r = subprocess.run(["ip", "netns", "exec", self.ns, sys.executable, str(PENDANT), str(self.port), cmds, want],
                           capture_output=True, text=True, timeout=60)
        assert r.returncode == 0, r.stderr
        return json.loads(r.stdout.strip().splitlines()[-1])

    def children(self, pid):
        """The direct children of `pid` (for a master killed with -9: its gateway is orphaned)."""
        try:
            return [int(c) for c in Path(f"/proc/{pid}/task/{pid}/children").read_text().split()]
        except OSError:
            return []

    def close(self):
        for pid in getattr(self, "orphans", []):
            try:
                os.kill(pid, signal.SIGTERM)
            except ProcessLookupError:
                continue
            deadline = time.monotonic() + 5
            while Path(f"/proc/{pid}").exists() and time.monotonic() < deadline:
                time.sleep(0.05)
            if Path(f"/proc/{pid}").exists():
                os.kill(pid, signal.SIGKILL)
        for p, log in reversed(self.procs):
            if p.poll() is None:
                p.terminate()
                try:
                    p.wait(timeout=10)
                except subprocess.TimeoutExpired:
                    p.kill()
                    p.wait()
            log.close()
        sh("ip", "netns", "del", self.ns, check=False)
        keep = os.environ.get("ECAT_KEEP_LOGS")  # a directory: the logs of every cell are kept there
        if keep:
            import shutil
            shutil.copytree(self.tmp.name, os.path.join(keep, self.ns), ignore=shutil.ignore_patterns("*.sock", "ev.db*"))
        self.tmp.cleanup()
        self.shm.cleanup()


def bus_config(tmp, **settings):
    cfg = json.loads((ROOT / "hal" / "ethercat" / "default-bus.json").read_text())
    # Issue 37: the safety containers' watchdog of every connection (ecat-sim gets the same)
    link_watchdog_ms = settings.pop("link_watchdog_ms", None)
    cfg.update(settings)
    if link_watchdog_ms is not None:
        for d in cfg["subdevices"]:
            for link in d.get("safety_links", []):
                link["watchdog_ms"] = link_watchdog_ms
    path = Path(tmp) / "bus.json"
    path.write_text(json.dumps(cfg))
    return str(path)


def emulator_answer_delay(c):
    """The emulator's own record of how late it answered (ecat-sim status `answers`, s): the
    largest time from a frame reaching its interface to the answer going out. A real ESC
    answers as the frame passes; 2 ms or more here is the host not running the emulator."""
    try:
        return (c.wire().get("answers") or {}).get("max_delay_us", 0.0) * 1e-6
    except (OSError, ValueError):
        return 0.0


def host_stalled(c):
    """A lockout that the host caused: FIELDBUS_LOST because no frame came back, with the
    loop's own wake-up 2 cycles late or more (the host did not run the loop's CPU, this VM's
    vCPU stalls, docs/ethercat.md "Host stalls": the emulator pinned to it could not answer
    either), or the emulator's own record showing an answer it gave 2 ms or more after the
    frame reached it (the host did not run the emulator: the master's loop was on time and the
    stand-in for the segment was not; a real ESC answers as the frame passes). Returns
    (whether it did, the larger of the two figures in s)."""
    s = c.status() or {}
    late = c.metric("safestate_cycle_lateness_max_seconds") or 0.0
    answered = emulator_answer_delay(c)
    log = c.log("run")
    # A stall past the subdevices' 10-cycle watchdog takes them out of OP instead: "left OP",
    # excused only when the loop itself was held that long.
    stalled = ("no frame came back" in log and max(late, answered) >= 0.002) or \
              ("subdevice left OP" in log and late >= 0.009)
    if "FIELDBUS_LOST" in s.get("alarms", []) and not stalled:
        print(f"FIELDBUS_LOST without a host stall on record: loop {late * 1e3:.2f} ms late at most, "
              f"emulator answered {answered * 1e3:.2f} ms late at most", flush=True)
    return "FIELDBUS_LOST" in s.get("alarms", []) and stalled, max(late, answered)


def stalled_at_start(c):
    """True when the cell locked out by a host stall (host_stalled) before it reached
    ESTOP_RESET_NEEDED. Stale cycles without such a stall are not excused: that is the
    master's fault, and the test goes on to fail on it."""
    deadline = time.monotonic() + 15
    while time.monotonic() < deadline:
        s = c.status() or {}
        if s.get("state") == "ESTOP_RESET_NEEDED":
            return False
        if s.get("state") == "ERROR_LOCKOUT":
            stalled, late = host_stalled(c)
            if stalled:
                print(f"start-up: FIELDBUS_LOST with the loop or the emulator {late * 1e3:.1f} ms late (a host stall); "
                      "the cell is started again, once", flush=True)
            return stalled
        time.sleep(0.05)
    return False


def fresh_cell():
    """A cell that got past its start, started once more if a host stall locked it out there
    (stalled_at_start)."""
    c = Cell()
    if stalled_at_start(c):
        c.close()
        c = Cell()
    return c


T1_LIMIT_MM_S = 250.0


def t1_verdict(c):
    """Whether the core raised T1_SPEED_EXCEEDED, and the emulated plant's own record since the
    last `plant reset`. The plant, paced by SYNC0, counts the pulses that applied more than one
    set-point at once (`multi_step`: frames the host delivered late past their SYNC0, so that an
    axis stood for a pulse and took two steps in the next, as a real drive would; cell.hpp) and
    the arm's peak point speed at those pulses and at every other one. An alarm is earned only
    when the arm itself went past the limit at such a pulse: then the core was right and the
    host's timing, not what the test exercises, made the arm fast. The test knows it from this
    record, it does not run again. Every T1 test here asserts, from the record:
      - at every pulse that applied one set-point the arm kept to the limit (the jog's own speed);
      - an alarm, if any, was earned (multi_step > 0 and the arm over the limit there)."""
    st = c.status() or {}
    plant = (c.wire() or {}).get("plant", {})
    alarmed = "T1_SPEED_EXCEEDED" in st.get("alarms", [])
    assert plant.get("max_point_speed_one_step_mm_s", 0.0) <= T1_LIMIT_MM_S, \
        ("the arm went over the T1 limit at a pulse that applied one set-point: the jog itself was too fast", plant)
    if alarmed:
        earned = plant.get("multi_step", 0) > 0 and plant.get("max_point_speed_multi_step_mm_s", 0.0) > T1_LIMIT_MM_S
        assert earned, ("T1_SPEED_EXCEEDED that the emulated arm did not earn", plant, st, c.log("run"))
        print(f"T1_SPEED_EXCEEDED earned: the emulated arm at {plant['max_point_speed_multi_step_mm_s']} mm/s at one of "
              f"{plant['multi_step']} SYNC0 pulses that applied more than one set-point (frames late on this host; "
              f"one-step peak {plant['max_point_speed_one_step_mm_s']} mm/s)", flush=True)
    return alarmed, plant


def host_stall_retry(test):
    """For the tests that are not about losing the bus: when one fails and the cell had locked
    out by a host stall (host_stalled: FIELDBUS_LOST with the loop itself woken two cycles late
    or more, correct by SPEC §4 rule 1 once BOOT is over), it runs once more on a fresh cell,
    saying so. A failure without that evidence, or twice, is a failure. (A T1 alarm the arm
    earned is not retried: the tests know it from the emulator's record, t1_verdict.)"""
    @functools.wraps(test)
    def wrapper(**kwargs):  # pytest passes the fixtures by name
        name, cell = next((k, v) for k, v in kwargs.items() if isinstance(v, Cell))
        try:
            return test(**kwargs)
        except AssertionError:
            stalled, late = host_stalled(cell)
            if not stalled:
                raise
            print(f"{test.__name__}: FIELDBUS_LOST with the loop or the emulator {late * 1e3:.1f} ms late (a host stall); "
                  "run once more on a fresh cell", flush=True)
            cell.close()
            again = fresh_cell()
            try:
                return test(**{**kwargs, name: again})
            finally:
                again.close()
    return wrapper


# Issue 40: a test whose subject is not the bus must not depend on the host never stalling.
# Those run on a bus that rides out a stall of this VM (10-30 ms, docs/ethercat.md "Host
# stalls"): FIELDBUS_LOST after 50 stale cycles in a row and the subdevices' output watchdogs at
# 50 cycles (the loop's own fieldbus watchdog stays at 100 ms), so that a stall leaves stale
# cycles, not a lockout, and nothing is run again; the black channel's containers (issue 37)
# likewise 50 ms instead of 10. Everything else is as shipped.
STALL_TOLERANT_BUS = {"stale_cycles": 50, "watchdog_cycles": 50, "link_watchdog_ms": 50}


@pytest.fixture
def cell():
    c = Cell(bus=STALL_TOLERANT_BUS)
    yield c
    c.close()


# The tests about the bus run it as shipped (FIELDBUS_LOST after 3 stale cycles in a row,
# 10-cycle output watchdogs): a cell that locks out on a loaded host fails them, except for one
# host stall during the start, which is not what any of them tests: then the cell is started
# once more (stalled_at_start), and the ones not about losing the bus run once more after a
# stall with evidence (host_stall_retry).
@pytest.fixture
def shipped_cell():
    c = fresh_cell()
    yield c
    c.close()


def test_boots_to_estop_reset_needed_over_ethercat(cell):
    s = cell.wait_state("ESTOP_RESET_NEEDED")
    assert "(EtherCAT," in cell.log("run")
    assert s["alarms"] == []
    assert all(sw & 0x4F == 0x40 for sw in s["statusword"])  # read from the emulated drives' TxPDOs
    assert cell.wire()["al_state"] == [8] * 11  # the distance sensor and the safe terminals too
    assert cell.wire()["reset_lamp"] is True  # the lamp bit of the DO terminal's RxPDO


def test_arming_then_estop_on_one_channel_opens_the_contactor_on_the_wire(cell):
    cell.wait_state("ESTOP_RESET_NEEDED")
    s = cell.pendant("reset,servo_on", "OPERATIONAL")
    assert s["state"] == "OPERATIONAL", (s, cell.log("run"))
    w = cell.wire()
    assert w["contactor"] is True and w["contactor_closed"] is True, (w, cell.status(), cell.log("run"), cell.log("sim"))
    assert all(cw == 0x000F for cw in w["controlword"])  # Enable operation on every drive
    stale0 = cell.metric("safestate_fieldbus_stale_cycles_total")
    assert cell.control_line("in estop.b=0") == "OK"
    cell.wait(lambda: cell.wire()["contactor"] is False, "contactor bit cleared on the wire", 5)
    # the input bit goes out in exchange k, the core opens the contactor in the cycle that
    # reads it, the cleared bit comes back in exchange k+1 (goal: at most 2 cycles, the
    # bench's figure: bench/ecat_reaction.py). A cycle whose answer came late (a host stall)
    # reads the input one exchange later: one more exchange per stale cycle meanwhile.
    reaction = cell.wire()["reaction"]
    stale = cell.metric("safestate_fieldbus_stale_cycles_total") - stale0
    assert reaction is not None and 1 <= reaction["cycles"] <= 2 + stale, (reaction, stale)
    print("reaction on the wire:", reaction, "stale cycles meanwhile:", stale)
    s = cell.status()
    assert s["contactor"] == "open" and "ESTOP_PRESSED" in s["alarms"], s
    # the other channel never followed: after discrepancy_ms the core locks out (SPEC §2)
    assert "ESTOP_DISCREPANCY" in cell.wait_state("ERROR_LOCKOUT")["alarms"]


# SPEC §14 on the segment (issue 36 items 1 and 2): on the shipped segment `safestate run`
# runs channel A and channel B as processes of their own on the EtherCAT backend by default
# (no --channels given here); the DO terminal carries K1 (A's) and K2 (B's), the DI terminal
# both auxiliary contacts, the drives 0x60E4. A channel stopped from outside: the other opens
# its own contactor on the wire and names CHANNEL_LOST. The window is the harness's
# stall-tolerant 50 cycles (docs/two-channels.md "On a shared host"); the time in cycles is
# test_pair's.
# @req CH-PROCESSES CH-CONTACTORS
@pytest.mark.parametrize("victim", ["A", "B"])
def test_two_channels_on_the_segment_each_opens_its_own_contactor_on_the_wire(victim):
    c = Cell(bus=STALL_TOLERANT_BUS, run_args=("--cross-check-cycles", "50"), channels=None)
    pid = None
    try:
        c.wait_state("ESTOP_RESET_NEEDED")
        assert "two channels (SPEC §14)" in c.log("run"), c.log("run")
        s = c.pendant("reset,servo_on", "OPERATIONAL")
        assert s["state"] == "OPERATIONAL", (s, c.log("run"))
        c.wait(lambda: c.wire()["contactor_closed"] and c.wire()["k2_closed"], "K1 and K2 closed on the segment", 5)
        w = c.wire()
        assert w["contactor"] is True and w["contactor_k2"] is True, w
        st = c.status()
        assert st["contactors"] == {"k1": "closed", "k2": "closed"}, st["contactors"]
        ch = {x["name"]: x for x in st["channels"]}
        assert ch["A"]["running"] and ch["B"]["running"] and ch["A"]["agree"] and ch["B"]["agree"], ch
        pid = ch[victim]["pid"]
        os.kill(pid, signal.SIGSTOP)
        other_bit = "contactor" if victim == "B" else "contactor_k2"  # the bit of the channel that runs on
        c.wait(lambda: c.wire()[other_bit] is False, f"{other_bit} cleared on the wire by the other channel", 5)
        st = c.wait_state("ERROR_LOCKOUT")
        assert "CHANNEL_LOST" in st["alarms"], st
        assert (c.alarm("CHANNEL_LOST") or {}).get("detail") == f"Safety channel {victim} lost", c.alarm("CHANNEL_LOST")
        c.wait(lambda: not (c.wire()["contactor_closed"] and c.wire()["k2_closed"]), "the power path open", 5)
    finally:
        if pid is not None:
            os.kill(pid, signal.SIGCONT)
        c.close()


def bus_without_k2(tmp):
    cfg = json.loads((ROOT / "hal" / "ethercat" / "default-bus.json").read_text())
    del cfg["subdevices"][0]["bits"]["contactor_fb.k2"]
    del cfg["subdevices"][1]["bits"]["contactor_k2"]
    path = Path(tmp) / "bus-without-k2.json"
    path.write_text(json.dumps(cfg))
    return str(path)


# A segment without K2 cannot carry SPEC §14's pair: by default it runs one channel and says
# so, naming what is missing (with --channels 2 it is refused: the test after this one).
def test_a_segment_without_k2_runs_one_channel_by_default_and_says_why(tmp_path):
    c = Cell(run_args=("--bus-config", bus_without_k2(tmp_path)), channels=None)
    try:
        c.wait_state("ESTOP_RESET_NEEDED")
        log = c.log("run")
        assert "one channel, not SPEC §14's two: the bus configuration has no K2" in log, log
        assert "two channels (SPEC §14)" not in log, log
        assert len(c.status()["channels"]) == 1, c.status()["channels"]  # one entry with one channel
    finally:
        c.close()


def test_two_channels_need_k2_and_the_load_side_encoders_in_the_bus_configuration(tmp_path):
    r = subprocess.run([BIN, "run", "--fieldbus", "ethercat", "--ifname", "lo", "--bus-config", bus_without_k2(tmp_path),
                        "--channels", "2", "--port", "18999", "--db", str(tmp_path / "ev.db")],
                       capture_output=True, text=True, timeout=30)
    assert r.returncode != 0, r
    assert "--channels 2: the bus configuration has no K2" in r.stderr, r.stderr


def test_guard_cat1_is_timed_on_the_wire_by_the_emulator(cell):
    """Issue 21 item 4: the guard opened while the demo program runs, timed by the emulator
    per exchange (`time cat1 from=input`, sim/ecat/src/wire_timing.cpp): the reaction is the
    first exchange whose commanded targets slow down, the safe state the contactor bit cleared
    at the end of the Cat 1 ramp."""
    cell.wait_state("ESTOP_RESET_NEEDED")

    def axis1_turning():
        q0, t0 = cell.wire()["joints"][0], time.monotonic()
        time.sleep(0.02)
        return abs(cell.wire()["joints"][0] - q0) / (time.monotonic() - t0) > 0.5

    # A Cat 1 reaction is the commanded speed falling: it can only be seen when the arm moves
    # at the trigger. The demo program dwells at its stations (0.4-0.6 s): a guard opened just
    # as a segment ends finds the targets still, and the first change on the wire is the
    # contactor at the end of a short ramp (70 cycles once, issue 40). Such a try measures
    # nothing about the reaction: the program is started again and the guard opened again.
    for attempt in range(3):
        s = cell.pendant("reset,servo_on,start", "OPERATIONAL")
        assert s["sub"] == "AUTO_RUNNING", s
        try:
            cell.wait(axis1_turning, "the demo program turning axis 1 at 0.5 rad/s", 15)
        except AssertionError as e:
            raise AssertionError(f"{e}; status {cell.status()}; wire plant {cell.wire().get('plant')}\n"
                                 f"run log:\n{cell.log('run')[-3000:]}") from None
        assert cell.control_line("time cat1 from=input") == "OK"
        stale0 = cell.metric("safestate_fieldbus_stale_cycles_total")
        assert cell.control_line("in gate.a=0") == "OK"
        time.sleep(0.005)  # the second channel within discrepancy_ms
        assert cell.control_line("in gate.b=0") == "OK"
        cell.wait(lambda: cell.wire()["wire_timing"]["safe"] is not None, "the contactor bit cleared after the ramp", 10)
        w = cell.wire()["wire_timing"]
        print("guard on the wire:", w)
        # Moving at the trigger: the commanded step well above the fall that counts as a reaction
        # (wire_timing.hpp kFallCounts, 2.5 counts a cycle; 0.5 rad/s is about 83).
        if w["speed_counts"] and w["speed_counts"][0] >= 25.0:
            break
        assert cell.control_line("in gate.a=1") == "OK" and cell.control_line("in gate.b=1") == "OK"
        cell.wait_state("IDLE")  # SPEC §4 row 4: STOPPING -> IDLE, PROTECTIVE_STOP latched until a reset
    else:
        raise AssertionError(f"the arm was never moving when the guard opened, in 3 tries: {w}")
    assert w["stop"] == "cat1" and w["early_exchange"] is None, w
    # `safestate rta --bus-config hal/ethercat/default-bus.json`: 2 cycles, worst case 1435 ms
    # (one exchange more per stale cycle meanwhile, as above)
    stale = cell.metric("safestate_fieldbus_stale_cycles_total") - stale0
    assert 1 <= w["reaction"]["cycles"] <= 2 + stale, (w, stale)
    assert w["reaction"]["cycles"] < w["safe"]["cycles"], w  # a ramp first, the power off at its end
    assert w["safe"]["us"] <= 1435000, w
    assert "PROTECTIVE_STOP" in cell.status()["alarms"]


def test_t1_jog_moves_the_emulated_axis(cell):
    cell.wait_state("ESTOP_RESET_NEEDED")
    assert cell.control_line("in mode=T1") == "OK"
    cell.pendant("reset", "IDLE")
    assert cell.control_line("in enable=centre") == "OK"  # in T1 power needs the enabling device held
    s = cell.pendant("servo_on", "OPERATIONAL")
    assert s["state"] == "OPERATIONAL" and s["mode"] == "T1", s
    assert cell.control_line("plant reset") == "OK"  # the plant's record (t1_verdict) from here
    before = cell.wire()["joints"][0]
    s = cell.pendant("jog:1:+:50", "OPERATIONAL")
    after = cell.wire()["joints"][0]
    alarmed, _ = t1_verdict(cell)  # an alarm only if the arm earned it
    assert s["sub"] == "MANUAL_JOGGING" or alarmed, s
    assert after > before + 0.01, (before, after, s)  # measured by the emulated drive, read back over the bus


@pytest.mark.parametrize("how", ["unplug", "kill", "link_down"])
def test_losing_the_bus_locks_out_with_fieldbus_lost(shipped_cell, how):
    cell = shipped_cell
    cell.wait_state("ESTOP_RESET_NEEDED")
    overruns = cell.metric("safestate_overruns_total")
    if how == "unplug":
        assert cell.control_line("fault unplug 8") == "OK"  # drive 6, the last on the line
    elif how == "kill":
        cell.sim.kill()
        killed = time.monotonic()
    else:
        sh("ip", "-n", cell.ns, "link", "set", "ecs", "down")
    s = cell.wait_state("ERROR_LOCKOUT", 10)
    if how == "kill":
        assert time.monotonic() - killed < 1.0, time.monotonic() - killed
    assert "FIELDBUS_LOST" in s["alarms"]
    if how != "unplug":
        # Issue 22 item 2: no exchange waits past its cycle; a frame not back within 3/4 of
        # the cycle leaves that cycle stale, and the third stale cycle in a row is
        # FIELDBUS_LOST. The time from the last answered frame (goal: within 5 cycles) is the
        # bench's figure (bench/ecat_loss.py: 3.8-3.9 ms, docs/performance.md); this test asserts
        # the count, and the time only with a margin a host stall of this VM (10-30 ms) does
        # not reach in practice and exchanges that waited out their frame timeout (20 ms each:
        # 60 ms for three) would: 40 ms.
        line = "FIELDBUS_LOST after 3 stale cycles, "
        cell.wait(lambda: line in cell.log("run"), "the log counting the stale cycles: " + line, 5)
        after = next(l for l in cell.log("run").splitlines() if line in l)
        print(how + ":", after)
        # "... 3 stale cycles, 3.712 ms after the last answered frame"
        ms = float(after.split(line, 1)[1].split(" ms ", 1)[0])
        assert 0 < ms <= 40.0, after
        assert cell.metric("safestate_fieldbus_stale_cycles_total") >= 3
        # No exchange held the loop while the bus was gone: the loop keeps cycling in
        # ERROR_LOCKOUT, and of the next 500 cycles (500 unanswered frames) hardly any cycle's
        # own work, the exchange included, took half its period (the histogram's buckets from
        # 0.524 ms on). An exchange that waited for its frame in the cycle would make every one
        # of them that slow (0.85 ms, its budget); a host stall during a cycle's work makes one
        # or two (it was seen once, issue 40): at most 5 (1 %) are allowed. Overruns, which
        # the host's late wake-ups cause too (`safestate rtbench` overran 8 times in 30 s on
        # this VM with no bus at all), are the bench's figure (bench/ecat_loss.py) and printed.
        def slow():
            m = cell.metrics("safestate_cycle_exec_seconds_count", 'safestate_cycle_exec_seconds_bucket{le="0.000524288"}')
            return m[0] - m[1]
        slow_before = slow()
        cycles = cell.metric("safestate_cycles_total")
        cell.wait(lambda: cell.metric("safestate_cycles_total") >= cycles + 500, "500 more cycles without a bus", 10)
        slow_after = slow()
        print(how + ": overruns while the bus was gone:", cell.metric("safestate_overruns_total") - overruns,
              "(host lateness: max", cell.metric("safestate_cycle_lateness_max_seconds"), "s); cycles whose own work "
              "took half a period or more:", slow_after - slow_before)
        assert slow_after - slow_before <= 5, ("cycles whose own work took half their period", slow_before, slow_after)
    named = ("FIELDBUS_LOST: subdevice 8 (drive axis 6): subdevice left OP" if how == "unplug" else
             "FIELDBUS_LOST: subdevice 1 (DI safety contacts) and every one after it: no frame came back")
    cell.wait(lambda: named in cell.log("run"), "the log naming what was lost: " + named, 5)
    # The alarm itself names the subdevice, as every client sees it (HMI, OPC UA, C#).
    text = cell.alarm("FIELDBUS_LOST")["detail"]
    assert text == ("Fieldbus lost at subdevice 8 (drive axis 6)" if how == "unplug" else
                    "Fieldbus lost: no answer from subdevice 1 (DI safety contacts) on"), text
    assert s["cause"] == text, s


def test_a_short_working_counter_alone_is_fieldbus_lost(shipped_cell):
    """Drive 6 (subdevice 8) stays in OP and answers every other datagram but stops
    processing process data: only the working counter of the cyclic exchange tells. The
    master locks out at once, for the bus as a whole, before the drive's own process-data
    watchdog takes it out of OP (which the "left OP" check would report, naming it)."""
    cell = shipped_cell
    cell.wait_state("ESTOP_RESET_NEEDED")
    assert cell.control_line("fault no-pd 12") == "ERROR no-pd needs a subdevice position 1..11"
    assert cell.control_line("fault no-pd 8") == "OK"
    s = cell.wait_state("ERROR_LOCKOUT", 10)
    assert "FIELDBUS_LOST" in s["alarms"], s
    named = "FIELDBUS_LOST: the bus as a whole: working counter differs from the expected one"
    cell.wait(lambda: named in cell.log("run"), "the log naming the bus: " + named, 5)
    assert "subdevice left OP" not in cell.log("run")
    text = cell.alarm("FIELDBUS_LOST")["detail"]
    assert text == "Fieldbus lost", text  # no subdevice to name: the bus as a whole
    assert s["cause"] == text, s


def test_late_frames_do_not_end_the_bus():
    """The emulator stalls 40 ms: the answers to the frames sent meanwhile come back after
    the master gave them up (each cycle waits 3/4 of a cycle, then it is stale). The frame
    thread drops them and the bus goes on (ethercrab's own frame task ended on such a frame,
    and every later exchange timed out: a permanent FIELDBUS_LOST). stale_cycles (1000) and
    the watchdog (1 s) are long here so that only a bus that never comes back can trip them
    (the black channel's containers' watchdog 1 s as well)."""
    c = Cell(run_args=["--watchdog-ms", "1000"],
             bus={"stale_cycles": 1000, "watchdog_cycles": 1000, "link_watchdog_ms": 1000})
    try:
        c.wait_state("ESTOP_RESET_NEEDED")
        for _ in range(5):
            c.sim.send_signal(signal.SIGSTOP)
            time.sleep(0.04)
            c.sim.send_signal(signal.SIGCONT)
            time.sleep(0.2)
        before = c.wire()["frames"]
        time.sleep(2.0)  # twice the watchdog
        s = c.status()
        assert s["state"] == "ESTOP_RESET_NEEDED" and s["alarms"] == [], (s, c.log("run"))
        assert c.wire()["frames"] > before + 500, "the master stopped exchanging frames"
        assert c.metric("safestate_fieldbus_stale_cycles_total") >= 5 * 30, "the stalls left no stale cycles"
        # The emulator's own record shows the stalls (what host_stalled reads to excuse a
        # lockout the host caused): answers given 40 ms after their frame reached it.
        answers = c.wire()["answers"]
        assert answers["max_delay_us"] >= 30000 and answers["late_1ms"] >= 5, answers
    finally:
        c.close()


# Not about the master finding the bus lost: a host stall that locked the cell out before the
# kill (once under a loaded ctest -j2, issue 40) is retried once with its evidence, as the others.
@host_stall_retry
def test_kill_9_of_the_master_drops_the_outputs_within_the_watchdog(shipped_cell):
    """Issue 22 item 3: the master writes every subdevice's process-data watchdog (10
    cycles by default: 0x0400 = 2498, 0x0420 = 100, 10 ms); killed with -9 in OPERATIONAL,
    its outputs stop, and the emulated DO terminal drops the contactor and the drives lose
    their enable within that time by themselves, measured at the emulator from the last
    exchange."""
    cell = shipped_cell
    cell.wait_state("ESTOP_RESET_NEEDED")
    assert "process-data watchdog 10 cycles (0x0400 = 2498, 0x0420 = 100)" in cell.log("run")
    assert cell.wire()["watchdog_us"] == [10000] * 11  # as the master wrote them (ESC default: 100000)
    s = cell.pendant("reset,servo_on", "OPERATIONAL")
    assert s["state"] == "OPERATIONAL", (s, cell.log("run"))
    w = cell.wire()
    assert w["contactor"] is True and all(cw == 0x000F for cw in w["controlword"]), w
    cell.orphans = cell.children(cell.run.pid)  # the gateway outlives a master killed with -9
    cell.run.kill()
    cell.run.wait(timeout=5)
    cell.wait(lambda: cell.wire()["output_drop"]["enable_us"] is not None, "the outputs dropped at the emulator", 5)
    w = cell.wire()
    drop = w["output_drop"]
    print("output drop after kill -9 of the master:", drop)
    assert w["contactor"] is False and all(cw == 0 for cw in w["controlword"]), w
    # Never before the watchdog expired (10 ms, as written above), and dropped by the watchdog
    # the master wrote, not the ESC's default (100 ms): within 50 ms. The figure itself, 10 ms
    # give or take the emulator's 1 ms poll, is the bench's (bench/ecat_loss.py: 10.6 ms,
    # docs/performance.md); a host stall of the emulator's CPU (10-30 ms here) delays its look.
    assert 10000 <= drop["contactor_us"] <= 50000, drop
    assert 10000 <= drop["enable_us"] <= 50000, drop


def test_one_percent_of_frames_lost_while_jogging_in_t1_raises_no_speed_alarm(cell):
    """Issue 22 item 2: one frame in 100 is processed by the emulated segment (the plant
    moves) but its answer never comes back: that cycle is stale, its positions held. The
    motion layer keeps the last speeds and differentiates the next sample over both
    cycles: a T1 jog at the 250 mm/s cap raises no T1_SPEED_EXCEEDED (it did when the
    next sample's two cycles of motion were divided by one).

    Not a test of the bus: it runs on the bus that rides out a host stall. On the bus as
    shipped a lost answer next to a wake-up 1.6 ms late made 3 stale cycles in a row once in
    a loop of full runs (FIELDBUS_LOST, correct for the bus, below the 2 ms stall evidence);
    a lost answer alone is never more than one stale cycle (`lose-every` never loses two in
    a row), and the 3-cycle rule is the bus tests' (test_losing_the_bus_..., the short
    working counter).

    Issue 40: the host may also deliver frames late past their SYNC0, and the emulated arm then
    really takes two steps in one pulse, over the cap: the core's alarm is right there. Every
    jog's outcome is judged by the emulator's own record (t1_verdict): no alarm the arm did not
    earn, and the jog itself within the cap. A jog an earned alarm stopped (Cat 0) does not count
    towards the frames lost while jogging: the cell is reset and jogs again, until 10 answers
    were lost in jogs that went on to their end (at most 5 jogs)."""
    cell.wait_state("ESTOP_RESET_NEEDED")
    assert cell.control_line("in mode=T1") == "OK"
    cell.pendant("reset", "IDLE")
    assert cell.control_line("in enable=centre") == "OK"
    assert cell.control_line("fault lose-every 100") == "OK"
    lost, stale, jogs, moved = 0, 0, 0, 0.0
    while lost < 10:
        assert jogs < 5, f"{jogs} jogs, {lost} answers lost in those that went on to their end"
        jogs += 1
        if (cell.status() or {}).get("state") != "OPERATIONAL":
            s = cell.pendant("servo_on", "OPERATIONAL")
            assert s["state"] == "OPERATIONAL" and s["mode"] == "T1", s
        assert cell.control_line("plant reset") == "OK"  # the arm's own record from here
        w0, stale0 = cell.wire(), cell.metric("safestate_fieldbus_stale_cycles_total")
        s = cell.pendant("jog:1:+:100", "OPERATIONAL")
        w = cell.wire()
        alarmed, plant = t1_verdict(cell)
        print(f"T1 jog {jogs} with 1 % frames lost:", w["lost_replies"] - w0["lost_replies"], "answers lost;",
              cell.metric("safestate_fieldbus_stale_cycles_total") - stale0, "stale cycles; plant", plant,
              "; SYNC0 of drive 1", w["dc"]["stats"][2], "; status", s, flush=True)
        if alarmed:
            cell.pendant("reset", "IDLE")  # earned (t1_verdict): this jog does not count
            continue
        assert s["sub"] == "MANUAL_JOGGING" and s["alarms"] == [], s
        st = cell.status()
        assert "T1_SPEED_EXCEEDED" not in st["alarms"] and st["state"] == "OPERATIONAL", st
        lost += w["lost_replies"] - w0["lost_replies"]
        stale += cell.metric("safestate_fieldbus_stale_cycles_total") - stale0
        moved += w["joints"][0] - w0["joints"][0]
    assert stale >= 10, stale  # each lost answer left a stale cycle
    assert moved > 0.05, moved  # it did jog


def test_a_segment_that_powers_up_after_the_controller_is_scanned_again():
    c = Cell(sim_late_s=1.5)
    try:
        s = c.wait_state("ESTOP_RESET_NEEDED", 20)
        assert s["alarms"] == [], s
        assert "EtherCAT scan 1: scan: timeout" in c.log("run")  # the first scan found nobody
    finally:
        c.close()


def test_wrong_product_id_is_boot_failed():
    c = Cell(sim_args=["--product", "3=0x1234"])
    try:
        s = c.wait_state("ERROR_LOCKOUT", 20)
        assert "BOOT_FAILED" in s["alarms"]
        a = c.alarm("BOOT_FAILED")
        assert a["detail"].startswith("Start-up failed: subdevice 3 (drive axis 1) has the wrong identity: "), a
        assert "product 0x00001234" in a["detail"], a
        # A wrong identity is known at the scan: BOOT fails in its first cycles, not at its timeout.
        assert a["since"] < 100, a
        assert "subdevice 3 (drive axis 1) has the wrong identity" in c.log("run")
        assert "product 0x00001234" in c.log("run")
    finally:
        c.close()


def test_wrong_revision_is_boot_failed():
    """The DI terminal's configuration names revision 0x00010000; the emulated one says 0x00020000."""
    c = Cell(sim_args=["--revision", "1=0x00020000"])
    try:
        s = c.wait_state("ERROR_LOCKOUT", 20)
        assert "BOOT_FAILED" in s["alarms"], s
        a = c.alarm("BOOT_FAILED")
        assert a["detail"].startswith("Start-up failed: subdevice 1 (DI safety contacts) has the wrong identity: "), a
        assert "revision 0x00020000" in a["detail"], a
        assert a["since"] < 100, a  # known at the scan
        assert ("subdevice 1 (DI safety contacts) has the wrong identity: vendor 0x00005AFE product 0x00D10018 "
                "revision 0x00020000, expected vendor 0x00005AFE product 0x00D10018 revision 0x00010000"
                in c.log("run")), c.log("run")
    finally:
        c.close()


def test_the_start_up_list_reaches_the_drives_in_pre_op(cell):
    """Issue 22 item 4: our master writes each drive's start-up SDOs (default-bus.json) in
    PRE-OP; the emulator's dictionaries hold them (CSP, 1 ms interpolation period, torque)."""
    cell.wait_state("ESTOP_RESET_NEEDED")
    w = cell.wire()
    assert w["sdo"][0] is None and w["sdo"][1] is None, w["sdo"]  # the I/O terminals: no mailbox
    for pos in range(2, 8):
        d = w["sdo"][pos]
        assert (d["6060:00"], d["60C2:01"], d["60C2:02"], d["6072:00"]) == (8, 1, -3, 1000), (pos, d)
    assert w["al_state"] == [8] * 11


def test_a_drive_that_refuses_an_sdo_fails_boot_naming_it():
    c = Cell(sim_args=["--sdo-refuse", "5 0x6072:0 0x06090030"])  # drive axis 3
    try:
        s = c.wait_state("ERROR_LOCKOUT", 20)
        assert "BOOT_FAILED" in s["alarms"], s
        a = c.alarm("BOOT_FAILED")
        want = ("Start-up failed: subdevice 5 (drive axis 3) refused start-up SDO 0x6072:00 = 1000: "
                "abort 0x06090030 (Value range of parameter exceeded")
        assert a["detail"].startswith(want), a
        assert a["since"] < 100, a  # known in PRE-OP, before the cycle starts
        assert "subdevice 5 (drive axis 3) refused start-up SDO 0x6072:00 = 1000: abort 0x06090030" in c.log("run")
        w = c.wire()
        # In order: the drive took 0x6060 before refusing 0x6072; the next drive got nothing,
        # and no subdevice went on to SAFE-OP.
        assert w["sdo"][4]["6060:00"] == 8 and w["sdo"][5]["6060:00"] == 0, w["sdo"]
        assert w["al_state"] == [2] * 11, w["al_state"]
    finally:
        c.close()


def test_hmi_sim_panel_drives_the_emulator(cell):
    """The gateway's `sim` message (as the HMI's panel sends it) reaches ecat-sim's contacts."""
    cell.wait_state("ESTOP_RESET_NEEDED")
    s = cell.pendant("sim:estop=pressed", "ESTOP_ACTIVE")
    assert s["state"] == "ESTOP_ACTIVE" and "ESTOP_PRESSED" in s["alarms"], s


def free_running_drives():
    """default-bus.json's subdevices with the drives free-running (no distributed clocks), for
    `ecat-sim --drives-free-run`."""
    subs = json.loads((ROOT / "hal" / "ethercat" / "default-bus.json").read_text())["subdevices"]
    for sd in subs:
        sd.pop("dc", None)
    return subs


@pytest.mark.parametrize("drives", ["dc", "free-run"])
def test_a_host_stall_during_the_boot_wait_does_not_fail_boot(drives):
    """Issue 40 item 2: ecat-sim freezes 15 ms at the master's first cyclic exchange after its
    OP request (`freeze 15 at-op`: no frame reaches the segment, as when the host stalls the
    master; the frames sent meanwhile arrive when it ends). The DO terminal's 10-cycle
    process-data watchdog expires and it falls back to SAFE-OP with AL status code 0x001B. With
    distributed clocks that is the master's wait for the drives' first SYNC0; with the drives
    free-running, its keep-alive's first exchange before the loop's first cycle (they fall back
    too, and the loop starts meanwhile: BOOT waits for the fieldbus up). The frame that starts
    the freeze goes unanswered, so no answer from before it shows the bus up. The
    master acknowledges the error and requests OP again, within the boot timeout, as real
    masters do; the cell boots. Once BOOT is over, SPEC §4 rule 1 stands: the same stall is
    FIELDBUS_LOST, and nothing is asked back (docs/decisions.md)."""
    free = drives == "free-run"
    c = Cell(sim_args=["--drives-free-run"] if free else [], bus={"subdevices": free_running_drives()} if free else None,
             sim_lines=["freeze 15 at-op"])
    try:
        s = c.wait_state("ESTOP_RESET_NEEDED", 20)
        assert s["alarms"] == [], s
        w = c.wire()
        assert w["freezes"] == 1, w  # the stall happened ...
        assert w["watchdog_expired"][1] >= 1, w["watchdog_expired"]  # ... and the DO terminal fell back
        if free:
            assert all(n >= 1 for n in w["watchdog_expired"][2:8]), w["watchdog_expired"]  # the drives too
        assert w["al_state"] == [8] * 11, w["al_state"]
        log = c.log("run")
        asked = [l for l in log.splitlines() if "error acknowledged, OP requested again" in l]
        print("\n".join(asked))
        assert any("subdevice 2 (DO contactor brakes lamp) fell back to AL state 4 with AL status code 0x001B" in l
                   for l in asked), log
        # After BOOT: rule 1 unchanged, the stall locks out and nothing is asked back.
        assert c.control_line("freeze 15") == "OK"
        s = c.wait_state("ERROR_LOCKOUT", 10)
        assert "FIELDBUS_LOST" in s["alarms"], s
        time.sleep(0.5)
        assert [l for l in c.log("run").splitlines() if "OP requested again" in l] == asked, c.log("run")
    finally:
        c.close()
