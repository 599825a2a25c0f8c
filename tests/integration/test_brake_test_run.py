"""The brake test at run time (SPEC §12, issue 21 items 1 and 4): `brake_test` through the
gateway, the status `safety.brake_test` object, a finished test kept in the event log as a
`brake_test` event and found again after a restart (the age of the last pass given to the
core: due_in_h counts on from it), and a failed test blocking AUTO across a restart. From
outside, against a real `safestate run` on loopback (the SafeState helper of test_gateway.py).

Run:  SAFESTATE_BIN=build/bin/safestate python -m pytest tests/integration/test_brake_test_run.py
"""
import json
import sqlite3
import sys
from datetime import datetime, timezone
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from test_gateway import ROOT, get_json, pendant, run  # noqa: E402
from test_safety_run import arm_in_auto, checksum, logged, start, stop, t1_idle  # noqa: E402

CFG = ROOT / "tests" / "scenarios" / "configs" / "brake-test.json"  # interval 8 h, grace 1 h
TEST_S = 15.0  # the test takes about 6.8 s of cycles


async def t1_armed(p):
    await p.state("ESTOP_RESET_NEEDED")
    await t1_idle(p)
    assert (await p.sim(set={"enable": "centre"}))["result"] == "OK"
    await p.status(lambda m: m["mode"] == "T1", what="T1")
    assert await p.command("servo_on") == "OK"
    await p.state("OPERATIONAL", "MANUAL_IDLE")


# @req BT-PERSIST BT-STATUS BT-REQUIRED BT-COMMAND
def test_a_pass_is_kept_across_a_restart(tmp_path):
    db = tmp_path / "events.db"
    code = checksum(CFG)
    s = start(tmp_path, CFG, db)
    try:
        st = get_json(s.port, "/api/status")
        assert st["safety"]["brake_test"] == {
            "due_in_h": None, "last": "none", "running": False, "axis": None, "progress": None,
            "due": True, "required": True, "last_time": None, "last_axis": None, "drift_deg": None,
        }, st["safety"]
        assert "BRAKE_TEST_DUE" in st["alarms"], "never tested, and the configuration asks for it"

        async def main():
            p = await pendant(s)
            await p.state("ESTOP_RESET_NEEDED")
            await t1_idle(p)
            assert await p.command("validate_config", code=code) == "OK"
            assert (await p.sim(set={"enable": "centre"}))["result"] == "OK"
            assert await p.command("servo_on") == "OK"
            await p.state("OPERATIONAL", "MANUAL_IDLE")
            mark = p.mark()
            assert await p.command("brake_test") == "OK"
            await p.state("OPERATIONAL", "BRAKE_TEST")
            # While it runs: the axis under test and the percentage of the whole test.
            m = await p.status(lambda m: m["safety"]["brake_test"]["running"]
                               and m["safety"]["brake_test"]["axis"] == 2, what="testing axis 2")
            assert 4 * 100 // 24 <= m["safety"]["brake_test"]["progress"] < 8 * 100 // 24, m["safety"]["brake_test"]
            ev = await p.event(lambda m: m["kind"] == "brake_test", since=mark, timeout=TEST_S, what="brake_test")
            assert ev["data"]["result"] == "passed" and ev["data"]["axis"] is None, ev
            assert len(ev["data"]["drift_deg"]) == 6 and max(ev["data"]["drift_deg"]) <= 0.5, ev
            m = await p.status(lambda m: m["safety"]["brake_test"]["last"] == "passed", what="last passed")
            bt = m["safety"]["brake_test"]
            assert 7.99 <= bt["due_in_h"] <= 8.0, bt
            assert not bt["running"] and bt["axis"] is None and bt["progress"] is None, bt
            assert not bt["due"] and not bt["required"], bt
            m = await p.status(lambda m: m["safety"]["brake_test"]["last_time"] is not None, what="the result on record")
            bt = m["safety"]["brake_test"]
            assert bt["last_time"] == ev["time"] and bt["last_axis"] is None, bt
            assert bt["drift_deg"] == ev["data"]["drift_deg"], bt
            assert "BRAKE_TEST_DUE" not in m["alarms"]
            assert m["sub"] == "MANUAL_IDLE"
            await p.close()
        run(main())
        assert [e["data"]["result"] for e in logged(s.port, "brake_test")] == ["passed"]
    finally:
        stop(s)

    # Started again with the same log: the pass is found again, due in a little under 8 h,
    # and AUTO may be armed.
    s = start(tmp_path, CFG, db)
    try:
        st = get_json(s.port, "/api/status")
        bt = st["safety"]["brake_test"]
        # Aged by the seconds between the pass and now (due_in_h is shown to 1/1000 h).
        assert bt["last"] == "passed" and 7.9 <= bt["due_in_h"] <= 8.0, bt
        assert bt["last_time"] is not None and len(bt["drift_deg"]) == 6, "found again in the log"
        assert bt["drift_deg"] == logged(s.port, "brake_test")[0]["data"]["drift_deg"], bt
        assert "BRAKE_TEST_DUE" not in st["alarms"]

        run(arm_in_auto(s))
    finally:
        stop(s)

    # A brake_test event whose drift list is malformed (written behind the gateway's back): the
    # core still counts the pass (run.cpp reads the result only), the status shows no record.
    now = datetime.now(timezone.utc)
    with sqlite3.connect(db) as con:
        con.execute("INSERT INTO events(t, time, kind, data) VALUES(?, ?, ?, ?)",
                    (1, now.strftime("%Y-%m-%dT%H:%M:%S.") + f"{now.microsecond // 1000:03d}Z", "brake_test",
                     json.dumps({"result": "passed", "axis": None, "drift_deg": [0, 0, 0, 0, 0]})))
    s = start(tmp_path, CFG, db)
    try:
        bt = get_json(s.port, "/api/status")["safety"]["brake_test"]
        assert bt["last"] == "passed" and bt["due_in_h"] > 7.99, bt
        assert bt["last_time"] is None and bt["last_axis"] is None and bt["drift_deg"] is None, bt
    finally:
        stop(s)


# @req BT-PERSIST BT-RULE10 BT-REQUIRED BT-SIM
def test_a_failure_blocks_auto_across_a_restart(tmp_path):
    db = tmp_path / "events.db"
    s = start(tmp_path, None, db)  # built-in configuration: no test required, a failed one blocks AUTO
    try:
        async def main():
            p = await pendant(s)
            await t1_armed(p)
            assert (await p.sim(fault="brake 3 weak"))["result"] == "OK"
            mark = p.mark()
            assert await p.command("brake_test") == "OK"
            ev = await p.event(lambda m: m["kind"] == "brake_test", since=mark, timeout=TEST_S, what="brake_test")
            assert ev["data"]["result"] == "failed" and ev["data"]["axis"] == 3, ev
            assert ev["data"]["drift_deg"][2] > 0.5, ev
            al = await p.event(lambda m: m["kind"] == "alarm" and m["data"]["name"] == "BRAKE_TEST_FAILED", since=mark)
            assert al["data"]["subject"] == "axis.3", al
            st = await p.state("IDLE")
            assert st["safety"]["brake_test"]["last"] == "failed", st["safety"]
            st = await p.status(lambda m: m["safety"]["brake_test"]["last_axis"] == 3, what="failed axis 3 on record")
            assert st["safety"]["brake_test"]["required"], "a failed test blocks AUTO"
            assert st["safety"]["brake_test"]["drift_deg"] == ev["data"]["drift_deg"], st["safety"]
            await p.close()
        run(main())
    finally:
        stop(s)

    s = start(tmp_path, None, db)
    try:
        assert get_json(s.port, "/api/status")["safety"]["brake_test"]["last"] == "failed"

        async def refused():
            p = await pendant(s)
            await p.state("ESTOP_RESET_NEEDED")
            assert await p.command("reset") == "OK"
            await p.state("IDLE")
            assert await p.command("servo_on") == "BRAKE_TEST_REQUIRED"
            await p.close()
        run(refused())
    finally:
        stop(s)
