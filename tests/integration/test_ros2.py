"""SafeState's ROS 2 adapter (issue 39, docs/ros2.md) from outside: a real `safestate run --ros2`
on the simulated cell, the adapter started and supervised by it, and a user's rclpy node in this
test's own process (tests/integration/ros2_user.py) that subscribes and calls as robot software
would. The physical world (E-stop, key switch, reduced input) is changed through the gateway's
`sim` messages from a loopback pendant, as in test_gateway.py.

Each cell gets a DDS domain of its own (from the pid) and DDS stays on this host, so parallel
runs do not hear each other. Every wait is bounded; times are asserted with wide margins (the
200 ms p99 of the E-stop is measured by bench/ros2_latency.py, not asserted here).

Run:  SAFESTATE_BIN=build/bin/safestate .venv-ros2/bin/python -m pytest tests/integration/test_ros2.py
"""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
from ros2_user import ROOT, ROS2_DIR, ROS2_PY, RosUser, dds_domain, diag_status, level, user_environment  # noqa: E402
from test_gateway import SafeState, booted, get_json, pendant, run, try_status, wait_until  # noqa: E402

OK, WARN, ERROR, STALE = 0, 1, 2, 3
FUNCTIONS = ("state", "E-stop", "guard", "enabling device", "mode", "drives", "fieldbus", "safety configuration",
             "safe limits", "brake test", "collaborative operation")
COMMANDS = ("servo_on", "servo_off", "start", "pause", "resume", "stop", "brake_test")
ESTOP_LOOSE_S = 1.0  # the issue: 200 ms p99 (bench/ros2_latency.py); asserted loosely here
STALE_S = 1.0  # the issue: STALE and unknown within 1 s of the gateway or the core going


def adapter_pids(cell):
    out = subprocess.run(["pgrep", "-P", str(cell.proc.pid), "-f", "safestate_ros2"], capture_output=True,
                         text=True).stdout.split()
    return [int(p) for p in out]


class RosCell:
    """`safestate run --ros2` on a DDS domain of its own, and a user's node on it."""

    def __init__(self, tmp_path, args=(), env=None, namespace=""):
        if not ROS2_PY.exists():
            pytest.fail(f"{ROS2_PY} missing: `make ros2` installs the ROS 2 adapter's venv")
        self.domain = dds_domain()
        extra = ["--ros2-namespace", namespace] if namespace else []
        self.cell = SafeState(tmp_path, args=["--ros2", "--ros2-domain-id", str(self.domain), *extra, *args],
                              env={**user_environment(), **(env or {})})
        self.user = RosUser(self.domain, namespace)

    def close(self):
        self.user.close()
        return self.cell.stop()

    def known(self, timeout=30.0):
        """The first SafetyState that knows the cell's state (the adapter up and connected)."""
        try:
            return self.user.state(lambda m: m.known, timeout, what="a known safety state")
        except AssertionError:
            raise AssertionError(f"the adapter never reported a known state: {self.cell.output()}") from None


@pytest.fixture
def ros(tmp_path):
    r = RosCell(tmp_path)
    yield r
    code = r.close()
    assert code == 0, f"safestate run exited {code} after SIGINT: {r.cell.output()}"


async def to_idle(cell):
    """A pendant on a cell in IDLE (AUTO: the remote role owns control)."""
    p = await booted(cell)
    assert await p.command("reset") == "OK"
    await p.state("IDLE")
    return p


# ------------------------------------------------------------------------------ topics
def test_topics_types_qos_and_services_as_documented(ros):
    m = ros.known()
    assert m.state == "ESTOP_RESET_NEEDED" and m.mode == "AUTO" and m.reset_needed, m
    assert m.config_checksum and m.config_validated and m.cycle > 0, m
    topics = ros.user.names_and_types()
    want = {"/safestate/safety_state": "safestate_msgs/msg/SafetyState",
            "/safestate/speed_scaling": "std_msgs/msg/Float64",
            "/safestate/events": "safestate_msgs/msg/Event",
            "/diagnostics": "diagnostic_msgs/msg/DiagnosticArray",
            "/joint_states": "sensor_msgs/msg/JointState"}
    for topic, typ in want.items():
        assert topics.get(topic) == [typ], f"{topic}: {topics.get(topic)}"
    # QoS: the state topics reliable and transient-local, so a late subscriber gets the value.
    for topic, durability in (("/safestate/safety_state", "TRANSIENT_LOCAL"),
                              ("/safestate/speed_scaling", "TRANSIENT_LOCAL"),
                              ("/safestate/events", "TRANSIENT_LOCAL"), ("/joint_states", "VOLATILE"),
                              ("/diagnostics", "VOLATILE")):
        infos = ros.user.node.get_publishers_info_by_topic(topic)
        assert len(infos) == 1, (topic, infos)
        q = infos[0].qos_profile
        assert (q.reliability.name, q.durability.name) == ("RELIABLE", durability), (topic, q)
    # A late subscriber: a second user node that joins now gets the current values at once
    # (nothing changes in ESTOP_RESET_NEEDED, so nothing is published again for a second).
    late = RosUser(ros.domain, name="late_user")
    try:
        m2 = late.state(lambda m: True, 10, what="the latched state")
        assert m2.known and m2.state == "ESTOP_RESET_NEEDED", m2
        _, s2 = late.wait("scaling", lambda m: True, 10, what="the latched speed scaling")
        assert s2.data == 0.0, s2
        assert late.got["state"][0][1].known, "the first state a late subscriber gets is the current one"
    finally:
        late.close()
    services = ros.user.services()
    for cmd in COMMANDS:
        assert services.get(f"/safestate/{cmd}") == ["std_srvs/srv/Trigger"], (cmd, services)
    assert "/safestate/reset" not in services and "/safestate/jog" not in services, \
        "no reset and no jog over ROS 2 (docs/ros2.md)"
    # Diagnostics: one status per safety function, named and levelled.
    # (The first array may be from before the adapter reached the gateway: every status STALE.)
    _, d = ros.user.wait("diag", lambda a: diag_status(a, "state") is not None and level(diag_status(a, "state")) != STALE,
                         10, what="diagnostics of a connected adapter")
    for f in FUNCTIONS:
        s = diag_status(d, f)
        assert s is not None, f"no diagnostics for {f}: {[x.name for x in d.status]}"
        assert s.hardware_id == "safestate"
    assert level(diag_status(d, "E-stop")) == WARN, "released, reset needed"
    assert level(diag_status(d, "fieldbus")) == OK
    values = {kv.key: kv.value for kv in diag_status(d, "safety configuration").values}
    assert values["checksum"] == m.config_checksum and values["validated"] == "true", values
    # SPEC §14: `safestate run` runs two channels; one status each, agreeing, named by compiler
    # (B is Clang's; A is this tree's compiler: GCC, or Clang in the sanitizer and coverage trees).
    for name, compilers in (("A", ("gcc", "clang")), ("B", ("clang",))):
        s = diag_status(d, "channel " + name)
        assert s is not None, f"no diagnostics for channel {name}: {[x.name for x in d.status]}"
        kv = {x.key: x.value for x in s.values}
        assert level(s) == OK and kv["compiler"] in compilers and kv["agree"] == "true" and kv["running"] == "true", kv


def sockets(pid):
    """(protocol, local address, port, state) of the sockets of process pid, from /proc."""
    inodes = set()
    for fd in os.listdir(f"/proc/{pid}/fd"):
        try:
            link = os.readlink(f"/proc/{pid}/fd/{fd}")
        except OSError:
            continue
        if link.startswith("socket:["):
            inodes.add(link[8:-1])
    out = []
    for proto in ("udp", "udp6", "tcp", "tcp6"):
        for line in open(f"/proc/net/{proto}").read().splitlines()[1:]:
            f = line.split()
            if f[9] in inodes:
                addr, port = f[1].split(":")
                if len(addr) == 8:  # IPv4, little-endian hex
                    addr = ".".join(str(int(addr[i:i + 2], 16)) for i in (6, 4, 2, 0))
                out.append((proto, addr, int(port, 16), f[3]))
    return out


def test_dds_receives_on_loopback_only(ros):
    """Nothing of the adapter listens beyond loopback (DDS has no authentication here): every UDP
    socket bound to 127.0.0.1, or to the discovery multicast group (joined on loopback only), and
    no TCP socket listening at all."""
    ros.known()
    socks = sockets(adapter_pids(ros.cell)[0])
    udp = [(a, p) for proto, a, p, _ in socks if proto.startswith("udp")]
    assert udp, "no UDP socket at all?"
    bad = [a for a in udp if a[0] not in ("127.0.0.1", "239.255.0.1")]
    assert not bad, f"the adapter binds beyond loopback: {bad} (all: {socks})"
    listening = [x for x in socks if x[0].startswith("tcp") and x[3] == "0A"]
    assert not listening, listening


# ------------------------------------------------------------------------------ E-stop
def test_estop_is_seen_in_safety_state_and_diagnostics(ros):
    ros.known()

    async def main():
        p = await to_idle(ros.cell)
        r = ros.user.call("servo_on")
        assert (r.success, r.message) == (True, "OK"), r
        await p.state("OPERATIONAL", "AUTO_IDLE")
        ros.user.state(lambda m: m.sub == "AUTO_IDLE", 10)
        s_mark, d_mark = ros.user.mark("state"), ros.user.mark("diag")
        t0 = time.monotonic()
        assert (await p.sim(set={"estop.a": 0, "estop.b": 0}))["result"] == "OK"
        t_state, m = ros.user.wait("state", lambda m: m.state == "ESTOP_ACTIVE", 10, s_mark, "ESTOP_ACTIVE")
        t_diag, d = ros.user.wait("diag", lambda a: level(diag_status(a, "E-stop")) == ERROR, 10, d_mark,
                                  "the E-stop diagnostics at ERROR")
        # `stop` says CAT0 for the one cycle of the Cat 0 stop only (SPEC §3): a 50 Hz status may miss it.
        assert "ESTOP_PRESSED" in m.alarms and m.stop in ("", "CAT0") and m.cause, m
        assert (m.contactor, m.drives, m.brakes) == ("open", "disabled", "engaged"), m
        assert m.speed_scaling == 0.0, "nothing may move in ESTOP_ACTIVE"
        e = diag_status(d, "E-stop")
        assert {kv.key: kv.value for kv in e.values}["reading"].startswith("pressed"), e.values
        assert any(kv.key == "alarm ESTOP_PRESSED" for kv in e.values), e.values
        # The alarm's name at once, then its words from GET /api/alarms (the cause's words).
        _, d = ros.user.wait("diag", lambda a: diag_status(a, "E-stop").message.startswith("E-stop "), 5, d_mark,
                             "the E-stop alarm in words")
        assert level(diag_status(d, "E-stop")) == ERROR
        assert level(diag_status(d, "state")) == ERROR
        assert t_state - t0 < ESTOP_LOOSE_S and t_diag - t0 < ESTOP_LOOSE_S, (t_state - t0, t_diag - t0)
        # Released: a reset is needed, which ROS cannot give.
        assert (await p.sim(set={"estop.a": 1, "estop.b": 1}))["result"] == "OK"
        ros.user.state(lambda m: m.state == "ESTOP_RESET_NEEDED" and m.reset_needed, 10)
    run(main())


# ------------------------------------------------------------------------------ commands
def test_start_works_from_auto_idle_and_is_refused_with_the_reason_otherwise(ros):
    ros.known()

    def call(cmd, ok, message, then=None, what=None):
        """~/cmd answered (success, message); then, if given, a state after the call (not one
        from before it) that satisfies `then`."""
        mark = ros.user.mark("state")
        r = ros.user.call(cmd)
        assert (r.success, r.message) == (ok, message), f"~/{cmd}: {r}"
        if then is not None:
            ros.user.state(then, 15, mark, what or f"the state after ~/{cmd}")

    async def main():
        p = await booted(ros.cell)
        call("start", False, "RESET_REQUIRED")  # ESTOP_RESET_NEEDED: a reset at the cell first
        mark = ros.user.mark("state")
        assert await p.command("reset") == "OK"
        ros.user.state(lambda m: m.state == "IDLE", 10, mark)
        call("start", False, "WRONG_STATE")  # IDLE: servo_on first
        call("servo_on", True, "OK", lambda m: m.sub == "AUTO_IDLE")
        call("start", True, "OK", lambda m: m.sub == "AUTO_RUNNING")
        call("start", False, "WRONG_STATE")  # already running: refused, not retried
        call("pause", True, "OK", lambda m: m.sub == "AUTO_PAUSED")
        call("resume", True, "OK", lambda m: m.sub == "AUTO_RUNNING")
        call("stop", True, "OK", lambda m: m.sub == "AUTO_IDLE")
        # The brake test (SPEC §12) from AUTO_IDLE at standstill: its sub-state, then its result
        # in the brake test's diagnostics (the test takes about 7 s of cycles).
        ros.user.wait("joints", lambda m: len(m.velocity) == 6 and max(abs(v) for v in m.velocity) < 1e-6, 15,
                      ros.user.mark("joints"), "standstill")
        d_mark = ros.user.mark("diag")
        call("brake_test", True, "OK", lambda m: m.sub == "BRAKE_TEST")
        ros.user.wait("diag", lambda a: "running" in diag_status(a, "brake test").message, 10, d_mark,
                      "the brake test running in diagnostics")
        mark = ros.user.mark("state")
        _, d = ros.user.wait("diag", lambda a: diag_status(a, "brake test").message == "last passed", 30, d_mark,
                             "the brake test passed in diagnostics")
        assert level(diag_status(d, "brake test")) == OK
        ros.user.state(lambda m: m.sub == "AUTO_IDLE", 10, mark)
        call("start", True, "OK", lambda m: m.sub == "AUTO_RUNNING")
        call("brake_test", False, "WRONG_STATE")  # only at AUTO_IDLE
        call("stop", True, "OK", lambda m: m.sub == "AUTO_IDLE")
        call("servo_off", True, "OK", lambda m: m.state == "IDLE")
        # T1: the pendant's mode; the remote role may not command (SPEC roles, protocol.md).
        assert (await p.sim(set={"mode": "T1"}))["result"] == "OK"
        ros.user.state(lambda m: m.mode == "T1" and m.owner == "pendant", 10, ros.user.mark("state") - 1)
        call("servo_on", False, "NOT_CONTROL_OWNER")
        # Each command the adapter sent is in the event log once, from the remote role.
        events = json.loads(json.dumps(get_json(ros.cell.port, "/api/events?after=0&limit=500")))
        cmds = [(e["data"]["cmd"], e["data"]["result"]) for e in events
                if e["kind"] == "command" and e["data"].get("from") == "remote"]
        assert cmds == [("start", "RESET_REQUIRED"), ("start", "WRONG_STATE"), ("servo_on", "OK"), ("start", "OK"),
                        ("start", "WRONG_STATE"), ("pause", "OK"), ("resume", "OK"), ("stop", "OK"),
                        ("brake_test", "OK"), ("start", "OK"), ("brake_test", "WRONG_STATE"), ("stop", "OK"),
                        ("servo_off", "OK"), ("servo_on", "NOT_CONTROL_OWNER")], cmds
    run(main())


# ------------------------------------------------------------------------------ joint states
def test_joint_states_move_with_the_simulated_arm(ros):
    ros.known()

    async def main():
        await to_idle(ros.cell)
        assert ros.user.call("servo_on").success
        ros.user.state(lambda m: m.sub == "AUTO_IDLE", 10)
        _, first = ros.user.wait("joints", lambda m: True, 10)
        assert list(first.name) == [f"joint_{i}" for i in range(1, 7)], first.name
        assert len(first.position) == 6
        status = try_status(ros.cell.port)
        assert status is not None
        assert ros.user.call("start").success
        mark = ros.user.mark("joints")
        _, moved = ros.user.wait("joints", lambda m: max(abs(a - b) for a, b in zip(m.position, first.position)) > 0.05,
                                 15, mark, "the joints to move by 0.05 rad")
        _, fast = ros.user.wait("joints", lambda m: len(m.velocity) == 6 and max(abs(v) for v in m.velocity) > 0.01,
                                15, mark, "a joint velocity")
        # What ROS says is what the gateway says (the same arm, within the status period).
        s = try_status(ros.cell.port)
        latest = ros.user.latest("joints")
        assert max(abs(a - b) for a, b in zip(latest.position, s["joints"])) < 0.5, (latest.position, s["joints"])
        mark = ros.user.mark("joints")
        t = time.monotonic()
        ros.user.wait("joints", lambda m: False if time.monotonic() - t < 1.0 else True, 5, mark)
        n = ros.user.mark("joints") - mark
        assert n >= 20, f"joint_states at the status rate (50 Hz): {n} in about 1 s"
        assert ros.user.call("stop").success
    run(main())


UR5_JOINTS = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint",
              "wrist_3_joint"]


def ur5_urdf():
    """example-robot-data's UR5 (Universal Robots' description) from the test venv (.venv:
    tests/integration/requirements-robots.txt, installed by `make test`; never copied here)."""
    py = ROOT / ".venv" / "bin" / "python"
    assert py.exists(), f"{py} missing: `make test` installs the test venv with example-robot-data"
    purelib = subprocess.run([str(py), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                             capture_output=True, text=True, check=True).stdout.strip()
    urdf = Path(purelib) / "cmeel.prefix/share/example-robot-data/robots/ur_description/urdf/ur5_robot.urdf"
    assert urdf.is_file(), f"{urdf} missing: pip install -r tests/integration/requirements-robots.txt into .venv"
    return str(urdf)


def test_joint_names_come_from_the_robot_description(tmp_path):
    """`safestate run --robot ur5_robot.urdf --ros2`: joint_states carry the UR5's joint names
    (the description the gateway serves at /api/robot), in every message from the first."""
    r = RosCell(tmp_path, args=["--robot", ur5_urdf()])
    try:
        r.known()
        served = [j["name"] for j in get_json(r.cell.port, "/api/robot")["joints"]]
        assert served == UR5_JOINTS, served
        r.user.wait("joints", lambda m: True, 10, what="joint_states")
        mark = r.user.mark("joints")
        r.user.wait("joints", lambda m: True, 10, mark + 10, "ten more joint_states")
        names = {tuple(m.name) for _, m in r.user.got["joints"]}
        assert names == {tuple(UR5_JOINTS)}, names
        s = try_status(r.cell.port)
        latest = r.user.latest("joints")
        assert max(abs(a - b) for a, b in zip(latest.position, s["joints"])) < 1e-3, (latest.position, s["joints"])
    finally:
        assert r.close() == 0, r.cell.output()


def test_ros2_is_off_by_default(tmp_path):
    cell = SafeState(tmp_path, env=user_environment())
    try:
        wait_until(lambda: try_status(cell.port) is not None, 30, "the gateway")
        time.sleep(1.0)  # an adapter would have been started with the gateway
        assert adapter_pids(cell) == [] and "ROS 2" not in cell.output(), cell.output()
    finally:
        assert cell.stop() == 0, cell.output()


# ------------------------------------------------------------------------------ speed scaling
def test_speed_scaling_falls_when_reduced_mode_comes(ros):
    ros.known()

    async def main():
        p = await to_idle(ros.cell)
        _, s0 = ros.user.wait("scaling", lambda m: True, 10)
        assert s0.data == 0.0, "IDLE: nothing may move"
        assert ros.user.call("servo_on").success
        _, full = ros.user.wait("scaling", lambda m: m.data == 1.0, 10, what="speed_scaling 1.0 in AUTO_IDLE")
        mark = ros.user.mark("scaling")
        assert (await p.sim(set={"reduced.a": 0, "reduced.b": 0}))["result"] == "OK"
        # The built-in configuration: normal 2000 mm/s, reduced 250 mm/s after a 500 ms ramp.
        _, low = ros.user.wait("scaling", lambda m: m.data <= 250.0 / 2000.0 + 1e-6, 10, mark,
                               "speed_scaling at the reduced limit")
        m = ros.user.state(lambda m: m.reduced and m.speed_scaling <= 0.125 + 1e-6, 10)
        assert "input" in " ".join(m.reduced_by) or m.reduced_by, m
        # Only falls (0 is "may not move", safe at any time: a host that stalls makes the state unknown).
        falling = [x.data for _, x in ros.user.got["scaling"][mark:] if x.data > 0.0]
        assert falling == sorted(falling, reverse=True), f"speed_scaling only falls: {falling}"
        _, d = ros.user.wait("diag", lambda a: "reduced" in diag_status(a, "safe limits").message, 10)
        assert (await p.sim(set={"reduced.a": 1, "reduced.b": 1}))["result"] == "OK"
        ros.user.wait("scaling", lambda m: m.data == 1.0, 10, what="speed_scaling back to 1.0")
        # T1: 250 mm/s at the TCP and every link origin (SPEC §4 rule 3), whatever the configuration.
        mark = ros.user.mark("state")
        assert ros.user.call("servo_off").success
        ros.user.state(lambda m: m.state == "IDLE", 10, mark, "IDLE after ~/servo_off")
        assert (await p.sim(set={"mode": "T1"}))["result"] == "OK"
        await p.status(lambda s: s["mode"] == "T1", what="T1")
        assert (await p.sim(set={"enable": "centre"}))["result"] == "OK"  # the enabling device held
        await p.status(lambda s: s["mode"] == "T1", what="T1")
        mark = ros.user.mark("scaling")
        assert await p.command("servo_on") == "OK"  # the pendant's, in T1
        await p.state("OPERATIONAL", "MANUAL_IDLE")
        m = ros.user.state(lambda m: m.sub == "MANUAL_IDLE", 10, what="MANUAL_IDLE in T1")
        _, t1 = ros.user.wait("scaling", lambda m: m.data > 0.0, 10, mark, "speed_scaling in T1")
        assert t1.data == pytest.approx(250.0 / 2000.0), t1
        assert m.mode == "T1" and m.speed_scaling == pytest.approx(0.125), m
    run(main())


def test_speed_scaling_follows_ssm_allowed_speed(tmp_path):
    """Speed and separation monitoring (SPEC §11, examples/safety/collaborative.json without its
    brake test: normal 1500 mm/s): speed_scaling is SSM's allowed speed over the normal one, 0 while SSM holds."""
    cfg = json.loads((ROOT / "examples" / "safety" / "collaborative.json").read_text())
    del cfg["brake_test"]  # no brake test due (SPEC §12: optional), so AUTO may power up at once
    path = tmp_path / "collaborative.json"
    path.write_text(json.dumps(cfg))
    r = RosCell(tmp_path, args=["--safety", str(path)])
    try:
        r.known()

        async def main():
            p = await booted(r.cell)
            assert (await p.sim(set={"mode": "T1"}))["result"] == "OK"
            await p.status(lambda s: s["mode"] == "T1", what="T1")
            assert await p.command("reset") == "OK"
            await p.state("IDLE")
            code = get_json(r.cell.port, "/api/status")["safety"]["checksum"]
            assert await p.command("validate_config", code=code) == "OK"
            assert (await p.sim(set={"mode": "AUTO"}))["result"] == "OK"
            await p.status(lambda s: s["mode"] == "AUTO" and s["owner"] == "remote", what="AUTO, the remote owning")
            mark = r.user.mark("state")
            assert (r.user.call("servo_on").message) == "OK"
            m = r.user.state(lambda m: m.sub == "AUTO_IDLE", 15, mark, "AUTO_IDLE")
            # No sensor reading yet: SSM holds (v_allowed 0), so nothing may move.
            assert m.speed_scaling == 0.0, m
            s_mark = r.user.mark("scaling")
            assert (await p.sim(set={"separation_mm": 800}))["result"] == "OK"
            # A person 800 mm away: SSM allows a speed well under the normal limit (the arm at
            # standstill, so the gateway's figure holds still), and speed_scaling says that much.
            r.user.wait("scaling", lambda m: m.data > 0.0, 10, s_mark, "speed_scaling under SSM")
            st = (await p.status(lambda s: s["safety"]["separation_mm"] == 800, what="separation 800"))["safety"]
            assert 0.0 < st["v_allowed"] < min(st["speed_limit"], 1500.0), st
            want = st["v_allowed"] / 1500.0
            r.user.wait("scaling", lambda m: abs(m.data - want) < 1e-9, 10, s_mark, f"speed_scaling {want}")
            assert abs(r.user.latest("scaling").data - want) < 1e-9, (r.user.latest("scaling"), st)
        run(main())
    finally:
        assert r.close() == 0, r.cell.output()


# ------------------------------------------------------------------------------ events
def test_events_arrive_once_and_in_order_across_a_gateway_restart(ros):
    ros.known()

    async def steps(p):
        assert await p.command("reset") == "OK"
        await p.state("IDLE")
        assert await p.command("servo_on") == "OK"
        await p.state("OPERATIONAL", "AUTO_IDLE")
        assert await p.command("servo_off") == "OK"
        await p.state("IDLE")

    async def main():
        p = await booted(ros.cell)
        mark = ros.user.mark("events")
        await steps(p)
        first = ros.user.wait("events", lambda m: True, 10, mark)[1].id
        gw = get_json(ros.cell.port, "/api/status")["gateway_pid"]
        os.kill(gw, signal.SIGKILL)
        # The core goes on; the gateway comes back (safestate run restarts it); events made at
        # once, while the adapter is still waiting for its next attempt, come from the log.
        wait_until(lambda: (s := try_status(ros.cell.port)) and s.get("gateway_pid") not in (None, gw), 20,
                   "the restarted gateway")
        p2 = await pendant(ros.cell)
        await p2.state("IDLE")
        await steps_after(p2)
        ros.user.state(lambda m: m.known and m.state == "IDLE", 20, ros.user.mark("state"),
                       "the adapter back on the restarted gateway")
        log = get_json(ros.cell.port, f"/api/events?after={first - 1}&limit=500")
        want = [e["id"] for e in log]
        wait_until(lambda: [m.id for m in ros.user.events()[mark:]][-1:] == want[-1:], 10,
                   "the last logged event on ~/events")
        got = ros.user.events()[mark:]
        ids = [m.id for m in got]
        assert ids == want, f"~/events: {ids}\nlog: {want}"
        by_id = {e["id"]: e for e in log}
        for m in got:
            e = by_id[m.id]
            assert (m.kind, m.time, m.cycle) == (e["kind"], e["time"], e["t"]), (m, e)
            assert json.loads(m.data) == e["data"], (m.data, e["data"])

    async def steps_after(p):
        assert (await p.sim(set={"mode": "T1"}))["result"] == "OK"
        await p.status(lambda s: s["mode"] == "T1", what="T1")
        assert (await p.sim(set={"mode": "AUTO"}))["result"] == "OK"
        await p.status(lambda s: s["mode"] == "AUTO", what="AUTO")
        assert await p.command("servo_on") == "OK"
        await p.state("OPERATIONAL", "AUTO_IDLE")
        assert await p.command("servo_off") == "OK"
        await p.state("IDLE")

    run(main())


# ------------------------------------------------------------------------------ liveness
def test_stale_and_unknown_when_the_core_stalls_and_known_again(ros):
    ros.known()
    mark = ros.user.mark("state")
    d_mark = ros.user.mark("diag")
    os.kill(ros.cell.proc.pid, signal.SIGSTOP)  # the core's loop stops; the gateway goes on
    t0 = time.monotonic()
    try:
        t_state, m = ros.user.wait("state", lambda m: not m.known, 10, mark, "the unknown state")
        t_diag, d = ros.user.wait("diag", lambda a: all(level(s) == STALE for s in a.status), 10, d_mark,
                                  "STALE diagnostics")
        # Why, in words: the gateway is up and says how old the core's heartbeat is.
        ros.user.wait("diag", lambda a: "core has not cycled" in diag_status(a, "state").message, 5, d_mark,
                      "STALE naming the core")
    finally:
        os.kill(ros.cell.proc.pid, signal.SIGCONT)
    assert m.state == "UNKNOWN" and m.speed_scaling == 0.0 and not m.alarms, m
    assert t_state - t0 < STALE_S and t_diag - t0 < STALE_S, (t_state - t0, t_diag - t0)
    ros.user.state(lambda m: m.known, 20, mark, "a known state after the core resumes")


def test_stale_and_unknown_when_the_gateway_hangs_and_known_again(ros):
    """A gateway that hangs with its socket open (SIGSTOP): no status, so unknown and STALE within
    1 s; the session survives a short hang and the state is known again once status flows."""
    ros.known()
    gw = get_json(ros.cell.port, "/api/status")["gateway_pid"]
    mark, d_mark = ros.user.mark("state"), ros.user.mark("diag")
    os.kill(gw, signal.SIGSTOP)
    t0 = time.monotonic()
    try:
        t_state, m = ros.user.wait("state", lambda m: not m.known, 10, mark, "the unknown state")
        t_diag, d = ros.user.wait("diag", lambda a: all(level(s) == STALE for s in a.status), 10, d_mark,
                                  "STALE diagnostics")
    finally:
        os.kill(gw, signal.SIGCONT)
    assert "no status from the gateway" in diag_status(d, "state").message, diag_status(d, "state").message
    assert t_state - t0 < STALE_S and t_diag - t0 < STALE_S, (t_state - t0, t_diag - t0)
    ros.user.state(lambda m: m.known, 20, mark, "a known state after the gateway resumes")
    assert ros.user.call("start").message == "RESET_REQUIRED", "the session and its commands go on"


def test_stale_and_unknown_when_the_core_dies(tmp_path):
    r = RosCell(tmp_path)
    pids, gw = [], None
    try:
        r.known()
        pids = adapter_pids(r.cell)
        assert len(pids) == 1, pids
        gw = get_json(r.cell.port, "/api/status")["gateway_pid"]
        mark, d_mark = r.user.mark("state"), r.user.mark("diag")
        t0 = time.monotonic()
        os.kill(r.cell.proc.pid, signal.SIGKILL)  # the core and its supervisor, at once
        t_state, m = r.user.wait("state", lambda m: not m.known, 10, mark, "the unknown state")
        t_diag, d = r.user.wait("diag", lambda a: all(level(s) == STALE for s in a.status), 10, d_mark,
                                "STALE diagnostics")
        assert m.state == "UNKNOWN" and m.speed_scaling == 0.0, m
        assert t_state - t0 < STALE_S and t_diag - t0 < STALE_S, (t_state - t0, t_diag - t0)
        # The orphaned adapter goes on trying, with back-off; it stops on SIGTERM, cleanly.
        os.kill(pids[0], signal.SIGTERM)
        wait_until(lambda: not alive(pids[0]), 10, "the adapter to stop on SIGTERM")
    finally:
        r.user.close()
        r.cell.stop()
        # Whatever the outcome, nothing of this cell outlives the test: the orphans (the adapter,
        # and the gateway should it not have noticed the core's death) and the segment.
        for pid in (*pids, gw):
            if pid and alive(pid):
                os.kill(pid, signal.SIGKILL)
        seg = Path(f"/dev/shm/safestate-{r.cell.port}")
        if seg.exists():
            seg.unlink()


def alive(pid):
    """pid runs (a zombie does not count)."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


# ------------------------------------------------------------------------------ roles and input
def test_the_adapter_is_a_remote_with_its_token_and_nothing_without(tmp_path):
    """With the gateway's tokens set, `safestate run --ros2` hands the remote token to the
    adapter through the environment (never argv); an adapter without it is refused and says
    nothing it does not know."""
    pend, rem = tmp_path / "pendant-token", tmp_path / "remote-token"
    pend.write_text("pendant-secret-1\n")
    rem.write_text("remote-secret-2\n")
    r = RosCell(tmp_path, args=["--pendant-token-file", str(pend), "--remote-token-file", str(rem)])
    try:
        m = r.known()
        assert m.state == "ESTOP_RESET_NEEDED", m
        pid = adapter_pids(r.cell)[0]
        argv = open(f"/proc/{pid}/cmdline").read()
        assert "secret" not in argv, argv
        # A second adapter on its own without the token: refused (BAD_TOKEN), state unknown.
        other = dds_domain() % 100 + 1
        env = {k: v for k, v in os.environ.items() if k != "SAFESTATE_REMOTE_TOKEN"}
        proc = subprocess.Popen([str(ROS2_PY), "-m", "safestate_ros2", "--ros-args", "-p",
                                 f"gateway:=127.0.0.1:{r.cell.port}", "-p", f"domain_id:={other}"],
                                env={**env, "PYTHONPATH": str(ROS2_DIR)}, stdout=subprocess.PIPE,
                                stderr=subprocess.STDOUT, text=True)
        try:
            u = RosUser(other, name="other_user")
            try:
                m = u.state(lambda m: True, 15, what="the adapter's state")
                time.sleep(2.0)
                assert all(not x.known for _, x in u.got["state"]), "known without the token"
            finally:
                u.close()
        finally:
            proc.send_signal(signal.SIGINT)
            out, _ = proc.communicate(timeout=10)
        assert "BAD_TOKEN" in out and "remote-secret" not in out, out
        assert proc.returncode == 0, out
    finally:
        r.close()


@pytest.mark.parametrize("param, words", [
    ("domain_id:=233", "domain_id: 233 out of range 0..232"),
    ("domain_id:=seven", "domain_id: not a whole number"),
    ("namespace:=/bad-name", "namespace: not a valid ROS namespace"),
    ("gateway:=nowhere", "gateway: expected HOST:PORT"),
    ("cycle_us:=5", "cycle_us: 5 out of range"),
    ("cycle_us:=fast", "cycle_us"),
    ("remote_token_file:=/nonexistent/token", "remote_token_file: No such file or directory"),
    ("localhost_only:=maybe", "localhost_only: expected true or false, got 'maybe'"),
    ("events_after:=-5", "events_after: -5 must be -1 or an event id"),
    ("gatway:=127.0.0.1:8080", "unknown parameter gatway"),
])
def test_bad_parameters_are_refused_with_their_name_and_exit_2(param, words):
    p = subprocess.run([str(ROS2_PY), "-m", "safestate_ros2", "--ros-args", "-p", param],
                       env={**os.environ, **user_environment(), "PYTHONPATH": str(ROS2_DIR)},
                       capture_output=True, text=True, timeout=60)
    assert p.returncode == 2, (p.returncode, p.stdout, p.stderr)
    assert words in p.stderr, p.stderr


def test_namespace_and_domain_are_parameters(tmp_path):
    r = RosCell(tmp_path, namespace="/cell7")
    try:
        m = r.known()
        assert m.state == "ESTOP_RESET_NEEDED"
        topics = r.user.names_and_types()
        assert "/cell7/safestate/safety_state" in topics and "/cell7/joint_states" in topics, topics
        from rcl_interfaces.srv import GetParameters  # noqa: PLC0415
        c = r.user.node.create_client(GetParameters, "/cell7/safestate/get_parameters")
        assert c.wait_for_service(timeout_sec=10)
        fut = c.call_async(GetParameters.Request(names=["domain_id", "namespace", "localhost_only"]))
        deadline = time.monotonic() + 10
        while not fut.done() and time.monotonic() < deadline:
            time.sleep(0.02)
        v = fut.result().values
        assert (v[0].integer_value, v[1].string_value, v[2].bool_value) == (r.domain, "/cell7", True), v
    finally:
        assert r.close() == 0


def test_the_inspection_script_of_the_docs_works(ros):
    """docs/ros2.md "Try it": adapters/ros2/tools/inspect_cell.py lists the topics, echoes
    ~/safety_state and calls ~/start, as a new user would in another shell."""
    ros.known()
    tool = [str(ROS2_PY), str(ROS2_DIR / "tools" / "inspect_cell.py"), "--domain", str(ros.domain), "--timeout", "30"]
    env = {**os.environ, **user_environment()}

    def run_tool(*args):
        return subprocess.run([*tool, *args], env=env, capture_output=True, text=True, timeout=60)

    p = run_tool("topics")
    assert p.returncode == 0, p.stderr
    assert "topic    /safestate/safety_state  safestate_msgs/msg/SafetyState  [reliable, transient_local]" in p.stdout, \
        p.stdout
    assert "service  /safestate/start  std_srvs/srv/Trigger" in p.stdout, p.stdout
    p = run_tool("echo")
    assert p.returncode == 0 and "state: ESTOP_RESET_NEEDED" in p.stdout and "known: True" in p.stdout, p
    p = run_tool("call", "start")
    assert p.returncode == 3, p
    assert p.stdout.strip() == "/safestate/start: success=False message=RESET_REQUIRED", p.stdout


def test_safestate_run_leaves_a_refusing_adapter_off_and_serves_on(tmp_path):
    """A setting the adapter refuses (exit 2) is not retried by `safestate run`, which serves on."""
    cell = SafeState(tmp_path, args=["--ros2", "--ros2-domain-id", str(dds_domain()), "--ros2-namespace", "/bad-name"])
    try:
        wait_until(lambda: "the ROS 2 adapter refused its configuration; ROS 2 stays off" in cell.output(), 30,
                   "safestate run to give up on the adapter")
        assert "namespace: not a valid ROS namespace" in cell.output(), cell.output()
        assert try_status(cell.port) is not None
        assert adapter_pids(cell) == []
    finally:
        assert cell.stop() == 0, cell.output()
