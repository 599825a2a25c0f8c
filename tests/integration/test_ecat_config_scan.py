"""`safestate ecat-config --scan IF` against `safestate ecat-sim` (issue 22 item 5): the bus
order read from the segment by our master, each subdevice matched to the shipped ESI; the
configuration made is the one `--device` makes, and the controller runs a scenario on it
over the emulated bus. A subdevice that no ESI describes is refused naming it.

Run as root (network namespaces, raw sockets):
  SAFESTATE_BIN=build/bin/safestate .venv/bin/python -m pytest tests/integration/test_ecat_config_scan.py
"""

import json
import os
import subprocess
import time
import uuid
from contextlib import contextmanager
from pathlib import Path

import pytest
from veth_ns import veth_namespace

ROOT = Path(__file__).resolve().parents[2]
BIN = os.environ.get("SAFESTATE_BIN", str(ROOT / "build" / "bin" / "safestate"))
ESI = str(ROOT / "hal" / "ethercat" / "esi" / "SafeState-Emulated.xml")
ORDER = ["--device", "0x00D10018", "--device", "0x00D00003", "--device", "0x00402001*6", "--device", "0x00D15001",
         "--device", "0x00D1F001", "--device", "0x00D0F001"]  # the safe terminals (issue 37) last


@pytest.fixture
def ns():
    with veth_namespace("ssesi") as name:
        yield name


@contextmanager
def ecat_sim(ns, tmp_path, *extra):
    control = str(tmp_path / ("ctl-%s.sock" % uuid.uuid4().hex[:6]))
    sim = subprocess.Popen(["ip", "netns", "exec", ns, BIN, "ecat-sim", "--ifname", "ecs", "--control", control, *extra],
                           stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 10
        while not os.path.exists(control):
            assert sim.poll() is None and time.monotonic() < deadline, "ecat-sim did not start"
            time.sleep(0.02)
        yield control
    finally:
        sim.terminate()
        sim.wait(timeout=10)


def ecat_config(ns, *args):
    return subprocess.run(["ip", "netns", "exec", ns, BIN, "ecat-config", "--esi", ESI, "--counts-per-rev", "1048576",
                           *args], capture_output=True, text=True, timeout=60)


def test_scan_makes_the_same_configuration_and_the_cell_runs_on_it(ns, tmp_path):
    scanned = tmp_path / "scanned.json"
    with ecat_sim(ns, tmp_path):
        r = ecat_config(ns, "--scan", "ecm", "--out", str(scanned))
    assert r.returncode == 0, r.stderr
    by_device = ecat_config(ns, *ORDER)
    assert by_device.returncode == 0, by_device.stderr
    got = json.loads(scanned.read_text())
    want = json.loads(by_device.stdout)
    assert "a scan of ecm" in got.pop("comment")
    want.pop("comment")
    assert got == want
    # The controller on the generated configuration over the emulated bus: a jog scenario
    # passes as it does with the built-in configuration (a fresh emulator: the scan left
    # the subdevices in PRE-OP).
    with ecat_sim(ns, tmp_path) as control:
        r = subprocess.run(["ip", "netns", "exec", ns, BIN, "replay", "--fieldbus", "ethercat", "--ifname", "ecm",
                            "--ecat-sim-control", control, "--bus-config", str(scanned),
                            str(ROOT / "tests" / "scenarios" / "cmd-jog.scn")],
                           capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stdout + r.stderr


def test_scan_refuses_a_subdevice_no_esi_describes(ns, tmp_path):
    out = tmp_path / "bus.json"
    with ecat_sim(ns, tmp_path, "--product", "3=0x00001234"):
        r = ecat_config(ns, "--scan", "ecm", "--out", str(out))
    assert r.returncode == 2
    assert ("subdevice 3 on the segment (vendor 0x00005AFE product 0x00001234 revision 0x00010000) is described "
            "by none of the ESI files") in r.stderr
    assert not out.exists()


def test_scan_of_a_silent_interface_is_refused(ns, tmp_path):
    out = tmp_path / "bus.json"
    r = ecat_config(ns, "--scan", "ecm", "--frame-timeout-us", "2000", "--out", str(out))
    assert r.returncode == 2
    assert "--scan ecm: " in r.stderr
    assert not out.exists()
