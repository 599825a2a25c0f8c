"""The scenarios of tests/scenarios/ over EtherCAT: `safestate replay --fieldbus ethercat`
runs the real controller on our ethercrab master against a fresh `safestate ecat-sim`
per file, over a veth pair in a namespace this test creates and removes. One exchange
per cycle keeps the emulator in lock-step, so every scenario whose outcome does not
hang on start-up timing or on same-cycle bus loss must pass exactly as in-process.

Run as root:  SAFESTATE_BIN=build/bin/safestate .venv/bin/python -m pytest tests/integration/test_ecat_replay.py
"""

import os
import subprocess
import time
import uuid
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
BIN = os.path.abspath(os.environ.get("SAFESTATE_BIN", str(ROOT / "build" / "bin" / "safestate")))
SCENARIOS = sorted((ROOT / "tests" / "scenarios").glob("*.scn"))

# Timing-dependent over a real bus, with the reason:
TIMING = {
    # the emulated drives power up while the master scans the bus, so BOOT ends sooner
    "ev-boot.scn": "start-up timing",
    "ev-boot-timeout.scn": "start-up timing",
    "set-01-reset-button-stuck.scn": "start-up timing (the press must begin while BOOT lasts)",
    "set-02-set-mode.scn": "start-up timing (a command answered while BOOT lasts)",
    "set-03-no-row-answers.scn": "start-up timing (a command answered while BOOT lasts)",
    # pins the exact cycle in which a link origin passes 250 mm/s: the emulated drives'
    # positions reach the core one exchange later than in-process
    "row03-t1-link-origin.scn": "exact cycle of a speed crossing",
    # a silent bus is found after the fieldbus watchdog (100 lost frames), not in the cycle of the fault
    "row01-fieldbus-lost.scn": "bus loss detected after the fieldbus watchdog",
    "res-check-order.scn": "bus loss detected after the fieldbus watchdog",
    # SPEC §11 SSM: the emulated segment has no distance sensor yet (ecat-sim refuses
    # separation_mm / separation_valid); the protective fields are on DI bits 20..23 and run
    "collab-ssm-v-allowed.scn": "no distance sensor on the emulated segment yet",
    "collab-ssm-hold.scn": "no distance sensor on the emulated segment yet",
    "collab-ssm-invalid.scn": "no distance sensor on the emulated segment yet",
    "collab-ssm-violated.scn": "no distance sensor on the emulated segment yet",
    "collab-rule9-auto-resume.scn": "no distance sensor on the emulated segment yet",
    "collab-field-discrepancy.scn": "no distance sensor on the emulated segment yet",
    "collab-outer-reduced.scn": "no distance sensor on the emulated segment yet",
    # the simulated person feeds only the in-process plant (docs/collaborative.md "The
    # simulated person"): behind a bus its `person` lines fail the run by design
    "collab-person-walk-in.scn": "the simulated person is not behind the emulated segment",
    "collab-person-far.scn": "the simulated person is not behind the emulated segment",
    "collab-person-ssm-hold.scn": "the simulated person is not behind the emulated segment",
}

pytestmark = pytest.mark.skipif(os.geteuid() != 0, reason="needs root: network namespaces and raw sockets")


@pytest.fixture(scope="module")
def ns():
    name = "ssscn-" + uuid.uuid4().hex[:8]
    subprocess.run(["ip", "netns", "add", name], check=True)
    try:
        subprocess.run(["ip", "-n", name, "link", "add", "ecm", "type", "veth", "peer", "name", "ecs"], check=True)
        for dev in ("ecm", "ecs", "lo"):
            subprocess.run(["ip", "-n", name, "link", "set", dev, "up"], check=True)
        yield name
    finally:
        subprocess.run(["ip", "netns", "del", name], check=False)


def replay(ns, scn, tmp_path):
    control = str(tmp_path / "ctl.sock")
    sim = subprocess.Popen(["ip", "netns", "exec", ns, BIN, "ecat-sim", "--ifname", "ecs", "--control", control],
                           stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 10
        while not os.path.exists(control):
            assert sim.poll() is None and time.monotonic() < deadline, "ecat-sim did not start"
            time.sleep(0.02)
        return subprocess.run(["ip", "netns", "exec", ns, BIN, "replay", "--fieldbus", "ethercat", "--ifname", "ecm",
                               "--ecat-sim-control", control, str(scn)], capture_output=True, text=True, timeout=120)
    finally:
        sim.terminate()
        sim.wait(timeout=10)


@pytest.mark.parametrize("scn", [s for s in SCENARIOS if s.name not in TIMING], ids=lambda s: s.name)
def test_scenario_passes_over_ethercat(ns, scn, tmp_path):
    r = replay(ns, scn, tmp_path)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "over EtherCAT" in r.stdout


def test_a_wrong_expectation_still_fails_over_ethercat(ns, tmp_path):
    scn = tmp_path / "wrong.scn"
    scn.write_text("@300 expect state=OPERATIONAL\n")
    r = replay(ns, scn, tmp_path)
    assert r.returncode == 1, r.stdout + r.stderr
    assert "expected state=OPERATIONAL, found state=ESTOP_RESET_NEEDED" in r.stdout
