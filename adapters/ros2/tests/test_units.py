"""Unit tests of the ROS 2 adapter's pure parts (no rclpy, no gateway): the mapping from the
gateway's status to what is published, the event sequencing across reconnects, the settings.
Run: .venv-ros2/bin/python -m pytest adapters/ros2/tests  (CTest ros2_units)."""

import fnmatch
import re
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from safestate_ros2 import backoff, config, mapping  # noqa: E402
from safestate_ros2.events import EventSequencer  # noqa: E402

OPERATIONAL = {
    "t": 1000, "state": "OPERATIONAL", "sub": "AUTO_RUNNING", "mode": "AUTO", "stop": None, "contactor": "closed",
    "drives": "enabled", "brakes": "released", "reset_lamp": "off", "tcp_speed": 300.0, "alarms": [],
    "joints": [0.1, 0.2, 0.3, 0.4, 0.5, 0.6], "owner": "remote", "cause": None,
    "safety": {"checksum": "3F9A01C2", "validated": True, "reduced": False, "reduced_by": [], "recovery": False,
               "speed_limit": 2000.0, "v_allowed": None, "fields": {"outer": "clear", "inner": "clear"},
               "brake_test": {"due_in_h": None, "last": "none", "running": False}},
}


def status(**kw):
    s = {**OPERATIONAL, "safety": dict(OPERATIONAL["safety"])}
    for k, v in kw.items():
        if k in s["safety"] and k not in s:
            s["safety"][k] = v
        else:
            s[k] = v
    return s


# ------------------------------------------------------------------ speed scaling
def test_speed_scaling_full_reduced_t1_ssm_and_stopped():
    assert mapping.speed_scaling(status(), 2000.0) == 1.0
    assert mapping.speed_scaling(status(speed_limit=250.0, reduced=True), 2000.0) == 0.125
    assert mapping.speed_scaling(status(speed_limit=1000.0), 2000.0) == 0.5  # the reduced ramp on its way
    assert mapping.speed_scaling(status(mode="T1"), 2000.0) == 0.125  # 250 mm/s
    assert mapping.speed_scaling(status(v_allowed=500.0), 2000.0) == 0.25  # SSM
    assert mapping.speed_scaling(status(v_allowed=0.0), 2000.0) == 0.0
    for state in ("IDLE", "STOPPING", "ESTOP_ACTIVE", "ERROR_LOCKOUT", "ARMING"):
        assert mapping.speed_scaling(status(state=state), 2000.0) == 0.0, state
    assert mapping.speed_scaling(None, 2000.0) == 0.0
    assert mapping.speed_scaling(status(), None) == 0.0  # the normal limit not known yet
    # Untrusted input: garbage is no limit at all, never a higher one.
    assert mapping.speed_scaling(status(speed_limit="fast"), 2000.0) == 1.0
    assert mapping.speed_scaling(status(speed_limit=5000.0), 2000.0) == 1.0
    assert mapping.speed_scaling(status(speed_limit=-5.0), 2000.0) == 0.0


def test_normal_speed_limit_from_the_safety_endpoint():
    assert mapping.normal_speed_limit({"config": {"tcp_max_speed_mm_s": 1500}}) == 1500.0
    assert mapping.normal_speed_limit({"config": {"tcp_max_speed_mm_s": -1}}) is None
    assert mapping.normal_speed_limit({"config": {}}) is None
    assert mapping.normal_speed_limit("x") is None


# ------------------------------------------------------------------ safety state
def test_safety_state_fields_and_unknown():
    st = mapping.safety_state(status(state="ESTOP_ACTIVE", sub=None, stop="CAT0", alarms=["ESTOP_PRESSED"],
                                     cause="E-stop channel A opened", reset_lamp="off"), 0.0)
    assert st["known"] and st["state"] == "ESTOP_ACTIVE" and st["sub"] == "" and st["stop"] == "CAT0"
    assert st["alarms"] == ["ESTOP_PRESSED"] and st["cause"] == "E-stop channel A opened"
    assert st["config_checksum"] == "3F9A01C2" and st["config_validated"] and st["cycle"] == 1000
    u = mapping.safety_state(None, 0.7)
    assert u == mapping.unknown_state() and u["state"] == "UNKNOWN" and not u["known"]
    bad = mapping.safety_state(status(state="DANCING", alarms="ESTOP_PRESSED", t=-3), 0.0)
    assert bad["state"] == "UNKNOWN" and not bad["known"] and bad["alarms"] == [] and bad["cycle"] == 0


# ------------------------------------------------------------------ joint names and states
URDF = """<robot name="r"><link name="base"/><link name="a"/><link name="b"/><link name="c"/><link name="d"/>
<link name="e"/><link name="f"/><link name="flange"/><link name="tool0"/>
<joint name="s" type="revolute"><parent link="base"/><child link="a"/></joint>
<joint name="l" type="revolute"><parent link="a"/><child link="b"/></joint>
<joint name="u" type="continuous"><parent link="b"/><child link="c"/></joint>
<joint name="r1" type="revolute"><parent link="c"/><child link="d"/></joint>
<joint name="b1" type="revolute"><parent link="d"/><child link="e"/></joint>
<joint name="t" type="revolute"><parent link="e"/><child link="f"/></joint>
<joint name="f-fixed" type="fixed"><parent link="f"/><child link="flange"/></joint>
<joint name="tool" type="fixed"><parent link="flange"/><child link="tool0"/></joint></robot>"""


# As Universal Robots' descriptions are laid out (example-robot-data's ur5_robot.urdf): a world
# link above the base, and fixed frames beside the chain (base, ee_link, tool0); a <joint>
# inside a <transmission> is no joint of the tree.
UR_LIKE = """<robot name="ur"><link name="world"/><link name="base_link"/><link name="base"/><link name="a"/>
<link name="b"/><link name="c"/><link name="d"/><link name="e"/><link name="f"/><link name="ee_link"/><link name="tool0"/>
<joint name="world_joint" type="fixed"><parent link="world"/><child link="base_link"/></joint>
<joint name="shoulder_pan_joint" type="revolute"><parent link="base_link"/><child link="a"/></joint>
<joint name="base_link-base_fixed_joint" type="fixed"><parent link="base_link"/><child link="base"/></joint>
<joint name="shoulder_lift_joint" type="revolute"><parent link="a"/><child link="b"/></joint>
<joint name="elbow_joint" type="revolute"><parent link="b"/><child link="c"/></joint>
<joint name="wrist_1_joint" type="revolute"><parent link="c"/><child link="d"/></joint>
<joint name="wrist_2_joint" type="revolute"><parent link="d"/><child link="e"/></joint>
<joint name="wrist_3_joint" type="revolute"><parent link="e"/><child link="f"/></joint>
<joint name="ee_fixed_joint" type="fixed"><parent link="f"/><child link="ee_link"/></joint>
<joint name="wrist_3_link-tool0_fixed_joint" type="fixed"><parent link="f"/><child link="tool0"/></joint>
<transmission name="t1"><joint name="shoulder_pan_joint"/></transmission></robot>"""
UR_NAMES = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint",
            "wrist_3_joint"]


def test_joint_names_from_the_best_source():
    six = ["a1", "a2", "a3", "a4", "a5", "a6"]
    assert mapping.joint_names({"joint_names": six}) == six
    assert mapping.joint_names({"joints": [{"name": n} for n in six]}) == six
    assert mapping.joint_names({"urdf": URDF}) == ["s", "l", "u", "r1", "b1", "t"]
    assert mapping.joint_names(URDF) == ["s", "l", "u", "r1", "b1", "t"]
    assert mapping.urdf_joint_names(UR_LIKE) == UR_NAMES  # fixed frames beside the chain are no branch
    assert mapping.joint_names({"urdf": UR_LIKE, "joints": "?"}) == UR_NAMES
    assert mapping.joint_names({"dh": []}, {"joint_names": six}) == six
    assert mapping.joint_names(None, None) == [f"joint_{i}" for i in range(1, 7)]
    # Refused sources: five names, repeats, not names, a branch, a prismatic joint, bad XML.
    for robot in ({"joint_names": six[:5]}, {"joint_names": ["a"] * 6}, {"joint_names": ["1x"] * 6},
                  {"urdf": URDF.replace('type="continuous"', 'type="prismatic"')},
                  {"urdf": URDF.replace('<parent link="e"/><child link="f"/>', '<parent link="d"/><child link="f"/>')},
                  {"urdf": "<robot"}, "<notarobot/>",
                  # a moving joint on a branch beside the arm (a second arm, a gripper finger)
                  UR_LIKE.replace('type="fixed"><parent link="base_link"/>', 'type="revolute"><parent link="base_link"/>'),
                  # a link with two parents
                  UR_LIKE.replace('<child link="tool0"/>', '<child link="e"/>')):
        assert mapping.joint_names(robot) == list(mapping.DEFAULT_JOINT_NAMES), robot


def test_joint_positions_and_velocities():
    a, b = status(t=1000), status(t=1020, joints=[0.12, 0.2, 0.3, 0.4, 0.5, 0.5])
    assert mapping.joint_positions(a) == [0.1, 0.2, 0.3, 0.4, 0.5, 0.6]
    v = mapping.joint_velocities(a, b, 1000)
    assert v == pytest.approx([1.0, 0.0, 0.0, 0.0, 0.0, -5.0])
    assert mapping.joint_velocities(None, b, 1000) is None
    assert mapping.joint_velocities(b, a, 1000) is None  # time went backwards
    assert mapping.joint_velocities(status(t=0), status(t=2000), 1000) is None  # 2 s apart: no velocity
    assert mapping.joint_positions(status(joints=[0.0] * 5)) is None
    assert mapping.joint_positions(status(joints=[0.0] * 5 + ["x"])) is None
    assert mapping.joint_positions(status(joints=[0.0] * 5 + [float("nan")])) is None


# ------------------------------------------------------------------ diagnostics
def by_name(entries):
    return {e["name"][len(mapping.PREFIX):]: e for e in entries}


def test_diagnostics_levels_follow_the_state_and_alarms():
    d = by_name(mapping.diagnostics(status()))
    assert set(d) == {"state", "E-stop", "guard", "enabling device", "mode", "drives", "fieldbus",
                      "safety configuration", "safe limits", "brake test", "collaborative operation"}
    assert all(e["level"] == mapping.OK for e in d.values()), {k: e["level"] for k, e in d.items()}
    info = {"ESTOP_PRESSED": {"severity": "info", "text": "The E-stop was pressed.", "detail": "E-stop channel A opened"}}
    d = by_name(mapping.diagnostics(status(state="ESTOP_ACTIVE", sub=None, stop="CAT0", alarms=["ESTOP_PRESSED"],
                                           cause="E-stop channel A opened"), info))
    assert d["E-stop"]["level"] == mapping.ERROR and d["E-stop"]["message"] == "E-stop channel A opened"
    assert ("reading", "pressed: Cat 0 stop, power removed") in d["E-stop"]["values"]
    assert ("alarm ESTOP_PRESSED", "info: E-stop channel A opened The E-stop was pressed.") in d["E-stop"]["values"]
    assert d["state"]["level"] == mapping.ERROR and d["state"]["message"] == "E-stop channel A opened"
    assert d["guard"]["level"] == mapping.OK
    info = {"FIELDBUS_LOST": {"severity": "lockout", "text": "Cyclic process data stopped being valid."}}
    d = by_name(mapping.diagnostics(status(state="ERROR_LOCKOUT", sub=None, alarms=["FIELDBUS_LOST"]), info))
    assert d["fieldbus"]["level"] == mapping.ERROR and d["fieldbus"]["message"].startswith("Cyclic")  # no detail
    assert d["drives"]["level"] == mapping.OK
    d = by_name(mapping.diagnostics(status(validated=False, alarms=["CONFIG_NOT_VALIDATED"]),
                                    {"CONFIG_NOT_VALIDATED": {"severity": "warning", "text": "Not validated."}}))
    assert d["safety configuration"]["level"] == mapping.WARN
    # An alarm the table does not know goes to "state", never nowhere.
    d = by_name(mapping.diagnostics(status(alarms=["NEW_THING"]), {"NEW_THING": {"severity": "fault"}}))
    assert d["state"]["level"] == mapping.ERROR and ("alarms", "NEW_THING") in d["state"]["values"]
    d = by_name(mapping.diagnostics(status(mode="NONE", alarms=["MODE_SELECTOR_INVALID"])))
    assert d["mode"]["level"] == mapping.ERROR


def test_diagnostics_stale_without_a_status():
    for entries in (mapping.diagnostics(None), mapping.stale_diagnostics("gateway: connection closed")):
        assert len(entries) == 11 and all(e["level"] == mapping.STALE for e in entries)
    assert mapping.stale_diagnostics("why")[0]["message"] == "why"


def test_one_status_per_channel_when_the_status_has_two():
    chans = [{"name": "A", "state": "OPERATIONAL", "cycle": 1000, "digest": "1A2B", "agree": True},
             {"name": "B", "state": "OPERATIONAL", "cycle": 1000, "digest": "1A2B", "agree": False}]
    d = by_name(mapping.diagnostics(status(channels=chans, alarms=["CHANNEL_MISMATCH"]),
                                    {"CHANNEL_MISMATCH": {"severity": "lockout", "text": "Channels differ."}}))
    assert d["channel A"]["level"] == mapping.ERROR  # the lockout alarm concerns both
    assert d["channel B"]["level"] == mapping.ERROR and ("digest", "1A2B") in d["channel B"]["values"]
    d = by_name(mapping.diagnostics(status(channels=[{"name": "A", "agree": True}, {"name": "B", "agree": False}])))
    assert d["channel A"]["level"] == mapping.OK and d["channel B"]["level"] == mapping.ERROR  # before any alarm
    d = by_name(mapping.diagnostics(status(channels=[{"state": "OPERATIONAL", "agree": True}, {"state": "IDLE"}])))
    assert d["channel A"]["level"] == mapping.OK and d["channel B"]["level"] == mapping.WARN
    assert "channel A" not in by_name(mapping.diagnostics(status()))
    # GET /api/status's channel fields (SPEC §14 as built): a process that ended is an ERROR,
    # the first field that differed is in the message; one channel publishes no channel status.
    a = {"name": "A", "compiler": "gcc", "pid": 11, "running": True, "answered": True, "state": "ERROR_LOCKOUT",
         "cycle": 5000, "digest": "9F00AA01", "agree": False, "differs_in": "state", "missing": 0, "late": 0}
    b = dict(a, name="B", compiler="clang", pid=12, running=False, answered=False, differs_in=None)
    d = by_name(mapping.diagnostics(status(channels=[a, b])))
    assert d["channel A"]["level"] == mapping.ERROR and d["channel A"]["message"].endswith("differs in state")
    assert d["channel B"]["level"] == mapping.ERROR and d["channel B"]["message"].startswith("process ended")
    assert ("compiler", "clang") in d["channel B"]["values"] and ("pid", "12") in d["channel B"]["values"]
    healthy = [dict(a, agree=True, differs_in=None, state="IDLE"), dict(b, running=True, answered=True, agree=True, state="IDLE")]
    d = by_name(mapping.diagnostics(status(channels=healthy, state="IDLE")))
    assert d["channel A"]["level"] == mapping.OK and d["channel B"]["level"] == mapping.OK
    assert "channel A" not in by_name(mapping.diagnostics(status(channels=[dict(a, agree=True)])))
    # CHANNEL_LOST names the channel that was lost (its subject): that channel's status says so,
    # the other's does not; before GET /api/alarms has answered, both carry it.
    lost = {"CHANNEL_LOST": {"severity": "lockout", "text": "A channel was lost.", "detail": "Safety channel B lost",
                             "subject": "B"}}
    both = [dict(a, agree=True, differs_in=None, state="ERROR_LOCKOUT"), dict(b, agree=True, state="ERROR_LOCKOUT")]
    d = by_name(mapping.diagnostics(status(channels=both, state="ERROR_LOCKOUT", alarms=["CHANNEL_LOST"]), lost))
    assert d["channel B"]["message"] == "Safety channel B lost" and ("alarms", "CHANNEL_LOST") in d["channel B"]["values"]
    assert d["channel A"]["level"] == mapping.OK and ("alarms", "none") in d["channel A"]["values"], d["channel A"]
    d = by_name(mapping.diagnostics(status(channels=both, state="ERROR_LOCKOUT", alarms=["CHANNEL_LOST"])))
    assert ("alarms", "CHANNEL_LOST") in d["channel A"]["values"] and ("alarms", "CHANNEL_LOST") in d["channel B"]["values"]


# ------------------------------------------------------------------ events
def ev(i, kind="transition"):
    return {"type": "event", "id": i, "t": i * 10, "time": "2026-11-22T10:00:00.000Z", "kind": kind, "data": {}}


def ids(evs):
    return [e["id"] for e in evs]


def test_first_connection_skips_history_then_publishes_live():
    s = EventSequencer()
    s.hold()
    assert s.offer(ev(11)) == []  # held while the log is read
    assert s.catch_up([ev(9), ev(10), ev(11)], publish=False) == []
    s.start_empty()
    assert ids(s.release()) == []  # 11 was history by the time the log was read
    assert ids(s.offer(ev(12))) == [12]
    assert ids(s.offer(ev(12))) == []  # a repeat is dropped


def test_reconnect_catches_up_from_the_log_without_repeats_or_gaps():
    s = EventSequencer(after=5)
    s.hold()
    assert s.offer(ev(9)) == [] and s.offer(ev(8)) == []  # live, while the log is read
    assert ids(s.catch_up([ev(6), ev(7), ev(8)])) == [6, 7, 8]
    assert ids(s.catch_up([ev(9)])) == [9]
    assert ids(s.release()) == []  # 8 and 9 came from the log already
    assert ids(s.offer(ev(10))) == [10]
    s.hold()  # the next connection: a held event newer than the log is released in order
    assert s.offer(ev(13)) == [] and s.offer(ev(12)) == []
    assert ids(s.catch_up([ev(11)])) == [11]
    assert ids(s.release()) == [12, 13]


def test_empty_log_and_bad_events():
    s = EventSequencer()
    s.hold()
    s.catch_up([], publish=False)
    s.start_empty()
    assert ids(s.release()) == [] and s.last == 0
    assert ids(s.offer(ev(1))) == [1]
    for bad in ({"id": "2"}, {**ev(2), "id": True}, {**ev(2), "id": 0}, {**ev(2), "kind": 3}, None, [ev(2)]):
        assert s.offer(bad) == []
    assert s.last == 1


# ------------------------------------------------------------------ settings
def test_early_settings_from_ros_args():
    argv = ["x", "--ros-args", "-p", "domain_id:=42", "--param", "namespace:=cell1", "-p", "localhost_only:=false"]
    assert config.early_settings(argv, {}) == (42, "/cell1", False)
    assert config.early_settings(["x"], {"ROS_DOMAIN_ID": "7"}) == (7, "", True)
    assert config.early_settings(["x", "--ros-args", "-p", "safestate:domain_id:=3"], {}) == (3, "", True)
    for argv, words in ((["--ros-args", "-p", "domain_id:=233"], "out of range"),
                        (["--ros-args", "-p", "domain_id:=-1"], "not a whole number"),
                        (["--ros-args", "-p", "namespace:=/a b"], "not a valid ROS namespace"),
                        (["--ros-args", "-p", "namespace:=/9a"], "not a valid ROS namespace"),
                        (["--ros-args", "-p", "localhost_only:=maybe"], "expected true or false")):
        with pytest.raises(config.ConfigError, match=words):
            config.early_settings(["x", *argv], {})
    with pytest.raises(config.ConfigError, match="ROS_DOMAIN_ID"):
        config.early_settings(["x"], {"ROS_DOMAIN_ID": "lots"})


def test_dds_environment_is_loopback_unless_asked():
    env = config.dds_environment({"ROS_LOCALHOST_ONLY": "1", "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST",
                                  "ROS_STATIC_PEERS": "10.0.0.1", "A": "1"}, True)
    assert not {"ROS_AUTOMATIC_DISCOVERY_RANGE", "ROS_LOCALHOST_ONLY", "ROS_STATIC_PEERS"} & set(env), env
    assert env["A"] == "1"
    assert env["FASTRTPS_DEFAULT_PROFILES_FILE"] == config.LOOPBACK_PROFILE
    assert Path(config.LOOPBACK_PROFILE).read_text().count("<address>127.0.0.1</address>") == 1
    assert config.dds_environment({"A": "1"}, False) == {"A": "1"}


def test_gateway_address_and_token(tmp_path, monkeypatch):
    assert config.gateway_address("127.0.0.1:8080") == ("127.0.0.1", 8080)
    assert config.gateway_address("cell-3.local:80") == ("cell-3.local", 80)
    for bad in ("127.0.0.1", ":80", "h:0", "h:70000", "h:8080/ws", ""):
        with pytest.raises(config.ConfigError):
            config.gateway_address(bad)
    f = tmp_path / "t"
    f.write_text("s3cret\n")
    assert config.read_token(str(f), {"SAFESTATE_REMOTE_TOKEN": "env"}) == "s3cret"
    assert config.read_token("", {"SAFESTATE_REMOTE_TOKEN": "env"}) == "env"
    with pytest.raises(config.ConfigError, match="remote_token_file"):
        config.read_token(str(tmp_path / "none"), {})


def test_backoff_matches_the_other_clients():
    assert [backoff.retry_ceiling_s(n) for n in (1, 2, 3, 4, 5, 6, 99)] == [0.5, 1, 2, 4, 8, 10, 10]
    assert backoff.retry_delay_s(1, random=lambda: 0.0) == 0.25
    assert backoff.retry_delay_s(3, random=lambda: 1.0) == 2.0


# ------------------------------------------------------------------ installation
ROOT = Path(__file__).resolve().parents[3]


def requirements():
    """(name, version) of every line of adapters/ros2/requirements.txt; a line that does not pin
    one version (==) fails the test."""
    out = []
    for line in (ROOT / "adapters" / "ros2" / "requirements.txt").read_text().splitlines():
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        m = re.fullmatch(r"([A-Za-z0-9_.\-]+)(\[[A-Za-z0-9_,\-]+\])?==([A-Za-z0-9_.+\-]+)", line)
        assert m, f"requirements.txt: not pinned to one version: {line!r}"
        out.append((m.group(1).lower(), m.group(3)))
    return out


def test_every_distribution_is_pinned_and_installed_at_that_version():
    from importlib.metadata import PackageNotFoundError, version  # noqa: PLC0415
    reqs = requirements()
    assert len(reqs) > 50 and ("ros-jazzy-rclpy", "7.1.6") in reqs, reqs[:5]
    wrong = []
    for name, want in reqs:
        try:
            got = version(name)
        except PackageNotFoundError:
            got = None
        if got != want:
            wrong.append((name, want, got))
    assert not wrong, f"the venv differs from requirements.txt (name, pinned, installed): {wrong}"


def test_every_distribution_has_its_licence_in_the_docs():
    doc = (ROOT / "docs" / "ros2.md").read_text()
    section = doc[doc.index("## Licences"):]
    names = set()
    for row in section.splitlines():
        if row.startswith("|") and not row.startswith("|---"):
            names.update(re.findall(r"`([a-z0-9\-*]+)`", row.split("|")[1]))
    missing = [n for n, _ in requirements() if not any(fnmatch.fnmatchcase(n, pat) for pat in names)]
    assert not missing, f"docs/ros2.md Licences does not name: {missing}"
