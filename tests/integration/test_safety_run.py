"""The safety configuration at run time (SPEC §10, issue 19 items 5 and the runtime half of 4):
`safestate run --safety FILE`, GET /api/safety, the status `safety` object, validate_config
through the gateway, the confirmation kept in the event log and found again after a
restart, and zone names in alarm words. From outside, against a real `safestate run` on
loopback (the SafeState helper of test_gateway.py).

Run:  SAFESTATE_BIN=build/bin/safestate python -m pytest tests/integration/test_safety_run.py
"""
import asyncio
import hashlib
import json
import signal
import subprocess
import sys
from pathlib import Path

import pytest
import rfc8785

sys.path.insert(0, str(Path(__file__).resolve().parent))
from test_gateway import BIN, ROOT, SafeState, free_port, get_json, pendant, run  # noqa: E402

CELL = ROOT / "examples" / "safety" / "cell.json"
SLOT = ROOT / "tests" / "scenarios" / "configs" / "slot-y60.json"
COLLAB = ROOT / "examples" / "safety" / "collaborative.json"
HEX8 = set("0123456789ABCDEF")


def checksum(path):
    """SPEC §10, computed here from RFC 8785 and SHA-256, not asked of SafeState."""
    doc = json.loads(Path(path).read_text(encoding="utf-8"))
    return hashlib.sha256(rfc8785.dumps(doc)).hexdigest()[:8].upper()


def start(tmp_path, safety=None, db=None):
    return SafeState(tmp_path, db=db, args=["--safety", str(safety)] if safety else [])


def stop(s):
    code = s.stop()
    assert code == 0, f"safestate run exited {code}: {s.output()}"


def logged(port, kind):
    """Every event of `kind` in the log (GET /api/events, page by page)."""
    found, after = [], 0
    while True:
        page = get_json(port, f"/api/events?after={after}&limit=500")
        found += [e for e in page if e["kind"] == kind]
        if len(page) < 500:
            return found
        after = page[-1]["id"]


async def t1_idle(p):
    assert (await p.sim(set={"mode": "T1"}))["result"] == "OK"
    await p.status(lambda s: s["mode"] == "T1", what="mode T1")
    assert await p.command("reset") == "OK"
    await p.state("IDLE")


async def arm_in_auto(s):
    """From boot: reset, servo_on in AUTO, OPERATIONAL/AUTO_IDLE (each answer OK)."""
    p = await pendant(s)
    await p.state("ESTOP_RESET_NEEDED")
    assert await p.command("reset") == "OK"
    await p.state("IDLE")
    assert await p.command("servo_on") == "OK"
    await p.state("OPERATIONAL", "AUTO_IDLE")
    await p.close()


def run_refused(db, path):
    """`safestate run --safety path`, expected to exit at once: (exit code, stdout, stderr).
    One that starts instead is stopped (Cat 1, SIGINT) and reported."""
    proc = subprocess.Popen([BIN, "run", "--no-opcua", "--port", str(free_port()), "--db", str(db), "--safety",
                             str(path)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=str(ROOT))
    try:
        out, err = proc.communicate(timeout=15)
    except subprocess.TimeoutExpired:
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=15)
        pytest.fail(f"safestate run started with {path}: {out} {err}")
    return proc.returncode, out, err


# @req LIM-RUN
def test_run_refuses_a_bad_file_naming_the_key(tmp_path):
    doc = json.loads(CELL.read_text(encoding="utf-8"))
    doc["joints"][2]["max_deg"] = "70"  # a number as a string
    doc["tool"]["colour"] = "red"        # an unknown key
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(doc), encoding="utf-8")
    db = tmp_path / "events.db"
    code, out, err = run_refused(db, bad)
    assert code == 2, (code, out, err)
    assert "joints[2].max_deg: must be a number" in err, err
    assert "tool.colour: unknown key" in err, err
    assert "SafeState running" not in out, "nothing may start"
    assert not db.exists(), "refused before anything started (not even the event log)"
    # A file that is not there, and one that is not JSON: the same refusal.
    for text in (None, "{ not json"):
        path = tmp_path / ("missing.json" if text is None else "broken.json")
        if text is not None:
            path.write_text(text, encoding="utf-8")
        code, out, err = run_refused(db, path)
        assert code == 2 and str(path) in err, (code, err)


# @req LIM-RUN LIM-PERSIST
def test_built_in_configuration_is_validated(tmp_path):
    s = start(tmp_path)
    try:
        st = get_json(s.port, "/api/status")
        assert st["safety"]["validated"] is True, st["safety"]
        assert "CONFIG_NOT_VALIDATED" not in st["alarms"]
        a = get_json(s.port, "/api/safety")
        assert a["source"] == "built-in" and a["validated"] is True and a["confirmation"] is None, a
        assert a["checksum"] == st["safety"]["checksum"]
        # The built-in configuration's checksum, as `safestate safety check --default` prints it.
        out = subprocess.run([BIN, "safety", "check", "--default"], capture_output=True, text=True, timeout=30).stdout
        assert f"checksum:  {a['checksum']}" in out, out
        assert hashlib.sha256(rfc8785.dumps(a["config"])).hexdigest()[:8].upper() == a["checksum"]
    finally:
        stop(s)


# @req LIM-RUN
def test_api_safety_and_status_shape(tmp_path):
    expected = checksum(CELL)
    s = start(tmp_path, CELL)
    try:
        a = get_json(s.port, "/api/safety")
        assert list(a) == ["name", "checksum", "source", "validated", "confirmation", "config"], a.keys()
        assert a["checksum"] == expected and set(a["checksum"]) <= HEX8
        assert a["source"] == str(CELL) and a["validated"] is False and a["confirmation"] is None
        assert a["config"] == json.loads(CELL.read_text(encoding="utf-8")), "the file's configuration, whole"
        assert a["name"] == a["config"]["name"]
        st = get_json(s.port, "/api/status")
        sf = st["safety"]
        assert list(sf) == ["checksum", "validated", "reduced", "reduced_by", "recovery", "speed_limit", "v_allowed",
                            "fields", "separation_mm", "brake_test",  # protocol.md's, then views.cpp's
                            "pfl", "contact_force", "contact_force_limit", "pfl_speed_limit"], sf
        assert sf["checksum"] == expected and sf["validated"] is False
        assert sf["reduced"] is False and sf["reduced_by"] == [] and sf["recovery"] is False
        assert sf["speed_limit"] == a["config"]["tcp_max_speed_mm_s"]
        assert sf["v_allowed"] is None and sf["separation_mm"] is None
        assert sf["fields"] == {"outer": "clear", "inner": "clear"}
        # protocol.md's two fields first, then views.cpp's (no brake_test key: none required).
        assert sf["brake_test"] == {"due_in_h": None, "last": "none", "running": False, "axis": None, "progress": None,
                                    "due": False, "required": False, "last_time": None, "last_axis": None,
                                    "drift_deg": None}, sf["brake_test"]
        assert list(sf["brake_test"])[:2] == ["due_in_h", "last"]
        assert sf["pfl"] is False and sf["contact_force"] is None, "no collaborative block: no PFL"
        assert sf["contact_force_limit"] is None and sf["pfl_speed_limit"] is None
        assert "CONFIG_NOT_VALIDATED" in st["alarms"]

        async def reduced_input():
            p = await pendant(s)
            assert (await p.sim(set={"reduced": "reduced"}))["result"] == "OK"
            m = await p.status(lambda m: m["safety"]["reduced"], what="reduced mode")
            assert m["safety"]["reduced_by"] == ["input"] and "REDUCED_SPEED" in m["alarms"], m["safety"]
            assert m["safety"]["speed_limit"] == a["config"]["reduced"]["tcp_max_speed_mm_s"] or \
                m["safety"]["speed_limit"] == a["config"]["tcp_max_speed_mm_s"]  # before / after the ramp
            al = [x for x in get_json(s.port, "/api/alarms") if x["name"] == "REDUCED_SPEED"]
            assert al and "reduced input" in al[0]["detail"], al
            assert (await p.sim(set={"reduced.a": 1, "reduced.b": 1}))["result"] == "OK"
            await p.status(lambda m: not m["safety"]["reduced"], what="normal speed again")
            await p.close()
        run(reduced_input())
    finally:
        stop(s)


# @req LIM-PERSIST LIM-VALIDATION
def test_validate_config_is_kept_across_a_restart(tmp_path):
    code = checksum(SLOT)
    wrong = "%08X" % (int(code, 16) ^ 1)
    db = tmp_path / "events.db"
    s = start(tmp_path, SLOT, db)
    try:
        async def main():
            p = await pendant(s)
            await p.state("ESTOP_RESET_NEEDED")
            await t1_idle(p)
            obs = await pendant(s, "observer")
            rem = await pendant(s, "remote")
            mark = p.mark()
            assert await obs.command("validate_config", code=code) == "NOT_CONTROL_OWNER"
            assert await rem.command("validate_config", code=code) == "NOT_CONTROL_OWNER"
            assert await p.command("validate_config", code=wrong) == "CHECKSUM_MISMATCH"
            for bad in (code.lower()[:7], code + "0", "0x" + code[2:], 123, None):
                assert await p.command("validate_config", code=bad) == "BAD_ARGUMENT", bad
            assert await p.command("validate_config") == "BAD_ARGUMENT"
            st = get_json(s.port, "/api/status")
            assert st["safety"]["validated"] is False and "CONFIG_NOT_VALIDATED" in st["alarms"]
            assert get_json(s.port, "/api/safety")["confirmation"] is None
            assert not [m for m in p.messages[mark:] if m["type"] == "event" and m["kind"] == "config_validated"]
            # The right code from the pendant, T1, IDLE.
            assert await p.command("validate_config", code=code) == "OK"
            ev = await p.event(lambda m: m["kind"] == "config_validated", since=mark)
            assert ev["data"] == {"checksum": code, "client": "pytest", "role": "pendant"}, ev
            await p.status(lambda m: m["safety"]["validated"] and "CONFIG_NOT_VALIDATED" not in m["alarms"],
                           what="validated")
            a = get_json(s.port, "/api/safety")
            assert a["validated"] is True
            assert a["confirmation"]["checksum"] == code and a["confirmation"]["client"] == "pytest"
            assert a["confirmation"]["time"] == ev["time"]
            for c in (p, obs, rem):
                await c.close()
        run(main())
        confirmations = logged(s.port, "config_validated")
        assert len(confirmations) == 1 and confirmations[0]["data"]["checksum"] == code, confirmations
    finally:
        stop(s)

    # Started again with the same file and log: validated, AUTO can be armed.
    s = start(tmp_path, SLOT, db)
    try:
        st = get_json(s.port, "/api/status")
        assert st["safety"]["validated"] is True and "CONFIG_NOT_VALIDATED" not in st["alarms"], st
        assert get_json(s.port, "/api/safety")["confirmation"]["checksum"] == code

        run(arm_in_auto(s))
    finally:
        stop(s)

    # Another file: a new checksum, not validated; the log still shows the last confirmation.
    s = start(tmp_path, CELL, db)
    try:
        st = get_json(s.port, "/api/status")
        assert st["safety"]["validated"] is False and st["safety"]["checksum"] == checksum(CELL)
        a = get_json(s.port, "/api/safety")
        assert a["validated"] is False and a["confirmation"]["checksum"] == code, a

        async def refused():
            p = await pendant(s)
            await p.state("ESTOP_RESET_NEEDED")
            assert await p.command("reset") == "OK"
            await p.state("IDLE")
            assert await p.command("servo_on") == "CONFIG_NOT_VALIDATED"
            await p.close()
        run(refused())
    finally:
        stop(s)


# @req LIM-ZONE LIM-PERSIST
def test_zone_name_in_alarm_words(tmp_path):
    code = checksum(SLOT)
    s = start(tmp_path, SLOT)
    try:
        async def main():
            p = await pendant(s)
            await p.state("ESTOP_RESET_NEEDED")
            await t1_idle(p)
            assert await p.command("validate_config", code=code) == "OK"
            assert (await p.sim(set={"mode": "AUTO"}))["result"] == "OK"
            await p.status(lambda m: m["mode"] == "AUTO", what="mode AUTO")
            assert await p.command("reset") == "OK"
            assert await p.command("servo_on") == "OK"
            await p.state("OPERATIONAL", "AUTO_IDLE")
            mark = p.mark()
            assert (await p.sim(fault="drive 1 runaway"))["result"] == "OK"
            ev = await p.event(lambda m: m["kind"] == "alarm" and m["data"]["name"] == "ZONE_VIOLATION", since=mark)
            # The second zone of the file (index 1): named, not numbered.
            assert ev["data"]["subject"] == "slot", ev
            assert "slot" in ev["data"]["detail"] and "Zone 2" not in ev["data"]["detail"], ev
            st = await p.state("IDLE")
            assert "ZONE_VIOLATION" in st["alarms"] and "slot" in st["cause"], st["cause"]
            al = [a for a in get_json(s.port, "/api/alarms") if a["name"] == "ZONE_VIOLATION"]
            assert al and al[0]["subject"] == "slot" and "slot" in al[0]["detail"], al
            assert (await p.sim(fault="clear all"))["result"] == "OK"
            await p.close()
        run(main())
    finally:
        stop(s)


# @req LIM-REDUCED
def test_reduced_zone_named_in_alarm_words(tmp_path):
    """REDUCED_SPEED from a reduced zone names the zone (the core's detail carries its index)."""
    s = start(tmp_path, ROOT / "tests" / "scenarios" / "configs" / "reduced-home.json")
    try:
        st = get_json(s.port, "/api/status")
        assert st["safety"]["reduced"] is True and st["safety"]["reduced_by"] == ["zone"], st["safety"]
        al = [a for a in get_json(s.port, "/api/alarms") if a["name"] == "REDUCED_SPEED"]
        assert al and "in reduced zone loading" in al[0]["detail"], al
    finally:
        stop(s)


# @req COL-FIELDS COL-COLLISION
def test_collaborative_status_and_the_value_faults_through_the_gateway(tmp_path):
    """SPEC §11 from outside: status `pfl`, `contact_force` (and the configuration's F_qs and
    v_pfl), the fields, and the `sim` message's `drive N torque_bias X` and `contact F` carried
    with their value through the bridge to the simulated cell: a torque bias on a held arm is
    a force the core estimates at the TCP (the arm stands still: no COLLISION)."""
    s = start(tmp_path, COLLAB)
    try:
        async def main():
            p = await pendant(s)
            st = await p.status()
            sf = st["safety"]
            assert sf["pfl"] is True, sf
            assert sf["contact_force"] == 0.0, "power off: the arm is not free, no estimate"
            # ISO/TS 15066 Annex A, hand: F_qs 140 N; v_pfl for 25 kg, 1.5 kg payload (collaborative.md).
            assert sf["contact_force_limit"] == 140.0, sf
            assert abs(sf["pfl_speed_limit"] - 1348) < 1.0, sf
            assert sf["fields"] == {"outer": "clear", "inner": "clear"}
            await p.state("ESTOP_RESET_NEEDED")
            await t1_idle(p)
            assert (await p.sim(set={"enable": "centre"}))["result"] == "OK"
            assert await p.command("servo_on") == "OK"
            await p.state("OPERATIONAL", "MANUAL_IDLE")
            await p.status(lambda m: m["safety"]["contact_force"] is not None and m["safety"]["contact_force"] < 10.0,
                           what="no force on the held arm")
            # A bad value changes nothing: the estimate stays low.
            e = await p.sim(fault="drive 2 torque_bias 400")
            assert e["type"] == "error" and "bad torque bias" in e["detail"], e
            await asyncio.sleep(0.3)
            assert (await p.status())["safety"]["contact_force"] < 10.0
            # The value arrives, fraction and all: twice the bias, twice the force (about 1.8 N
            # per % on axis 2 in this pose).
            assert (await p.sim(fault="drive 2 torque_bias 25.5"))["result"] == "OK"
            m = await p.status(lambda m: 30.0 < m["safety"]["contact_force"] < 60.0, what="the bias read as a force at the TCP")
            f1 = m["safety"]["contact_force"]
            assert (await p.sim(fault="drive 2 torque_bias 51"))["result"] == "OK"
            m = await p.status(lambda m: abs(m["safety"]["contact_force"] - 2 * f1) < 0.1 * f1, what="twice the force")
            assert m["state"] == "OPERATIONAL" and "COLLISION" not in m["alarms"], "standing still: no rule 8"
            assert (await p.sim(fault="drive 2 torque_bias 0"))["result"] == "OK"
            await p.status(lambda m: m["safety"]["contact_force"] < 10.0, what="the bias gone")
            assert (await p.sim(fault="contact 150"))["result"] == "OK"
            assert (await p.sim(fault="contact 0"))["result"] == "OK"
            # The fields as the status shows them.
            assert (await p.sim(set={"field.outer": "interrupted"}))["result"] == "OK"
            await p.status(lambda m: m["safety"]["fields"] == {"outer": "interrupted", "inner": "clear"},
                           what="the outer field interrupted")
            assert (await p.sim(set={"field.outer": "clear"}))["result"] == "OK"
            await p.status(lambda m: m["safety"]["fields"]["outer"] == "clear", what="clear again")
            await p.close()
        run(main())
    finally:
        stop(s)


def test_pfl_on_a_ur5_starts_and_reads_its_drives_torques(tmp_path):
    """Issue 38: collaborative operation with PFL on another arm than the built-in IRB 120. A
    UR5 (example-robot-data, the test venv) with `collaborative.pfl.enabled` starts; the core's
    collision model is the UR5's, so the held arm shows no force, and a torque bias on axis 2
    (per mille of the UR5's rated torque, its URDF effort) is read as a force at the TCP."""
    import sysconfig
    ur5 = (Path(sysconfig.get_paths()["purelib"]) / "cmeel.prefix" / "share" / "example-robot-data" / "robots" /
           "ur_description" / "urdf" / "ur5_robot.urdf")
    assert ur5.is_file(), "example-robot-data missing: pip install -r tests/integration/requirements-robots.txt"
    cfg = ROOT / "tests" / "scenarios" / "ur5" / "configs" / "pfl-abdomen.json"
    s = SafeState(tmp_path, args=["--robot", str(ur5), "--safety", str(cfg)])
    try:
        async def main():
            p = await pendant(s)
            sf = (await p.status())["safety"]
            assert sf["pfl"] is True, sf
            assert sf["contact_force_limit"] == 110.0, sf  # abdomen
            await p.state("ESTOP_RESET_NEEDED")
            await t1_idle(p)
            assert (await p.sim(set={"enable": "centre"}))["result"] == "OK"
            assert await p.command("servo_on") == "OK"
            await p.state("OPERATIONAL", "MANUAL_IDLE")
            await p.status(lambda m: m["safety"]["contact_force"] is not None and m["safety"]["contact_force"] < 5.0,
                           what="no force on the held UR5")
            assert (await p.sim(fault="drive 2 torque_bias 25"))["result"] == "OK"
            # 25 % of the UR5's 150 N m is 37.5 N m, some 49 N at the TCP 0.77 m out in this pose
            # (read in per mille of the IRB 120's 60 N m it would be some 20 N).
            m = await p.status(lambda m: 35.0 < m["safety"]["contact_force"] < 65.0, what="the bias read as a force")
            assert m["state"] == "OPERATIONAL" and "COLLISION" not in m["alarms"], "standing still: no rule 8"
            assert (await p.sim(fault="drive 2 torque_bias 0"))["result"] == "OK"
            await p.status(lambda m: m["safety"]["contact_force"] < 5.0, what="the bias gone")
        run(main())
    finally:
        stop(s)
