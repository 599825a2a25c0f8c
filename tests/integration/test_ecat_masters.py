"""Does `safestate ecat-sim` speak standard EtherCAT? Two independent masters from PyPI,
pysoem (SOEM) and kickcat, scan the emulated segment over a veth pair in a network
namespace this test creates and removes, bring it to OP and read the identities, the
PDO sizes, the CiA 402 statuswords and the safety contacts; pysoem also reads and writes
the drives' CoE objects (SDO) and gets the standard abort codes.

Run as root (network namespaces, raw sockets):
  SAFESTATE_BIN=build/bin/safestate .venv/bin/python -m pytest tests/integration/test_ecat_masters.py
"""

import json
import os
import subprocess
import sys
import tempfile
import time
import uuid
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
BIN = os.environ.get("SAFESTATE_BIN", str(ROOT / "build" / "bin" / "safestate"))
PROBE = Path(__file__).resolve().parent / "ecat" / "probe.py"
sys.path.insert(0, str(PROBE.parent))
from probe import control  # noqa: E402  (one line to the emulator's control socket)

VENDOR = 0x5AFE
# the distance sensor (SPEC §11), then the safe input and output terminals (issue 37)
PRODUCTS = [0xD10018, 0xD00003] + [0x402001] * 6 + [0xD15001, 0xD1F001, 0xD0F001]
REVISION = 0x10000
COUNT = len(PRODUCTS)
# drives: 0x6041, 0x6064, 0x606C, 0x6077, 0x60E4:01 and two 19-byte safety containers; sensor: mm (i32),
# valid; F-DI: two 19-byte containers (the contacts to A and to B), F-DO: two 16-byte ones
IN_BYTES = [4, 0] + [54] * 6 + [5, 38, 32]
# drives: 0x6040, 0x607A, 0x6072 and two 15-byte containers; F-DI two 15-byte, F-DO two 16-byte
OUT_BYTES = [0, 2] + [38] * 6 + [0, 30, 32]


def sh(*args, check=True):
    return subprocess.run(args, check=check, capture_output=True, text=True, timeout=30)


class Segment:
    """A namespace with a veth pair: ecat-sim on `ecs`, the master on `ecm`."""

    def __init__(self, extra=()):
        self.ns = "ssecat-" + uuid.uuid4().hex[:8]
        self.tmp = tempfile.TemporaryDirectory(prefix="ssecat-")
        self.control = os.path.join(self.tmp.name, "ctl.sock")
        sh("ip", "netns", "add", self.ns)
        try:
            sh("ip", "-n", self.ns, "link", "add", "ecm", "type", "veth", "peer", "name", "ecs")
            for dev in ("ecm", "ecs", "lo"):
                sh("ip", "-n", self.ns, "link", "set", dev, "up")
            self.log = open(os.path.join(self.tmp.name, "sim.log"), "w")
            self.proc = subprocess.Popen(
                ["ip", "netns", "exec", self.ns, BIN, "ecat-sim", "--ifname", "ecs", "--control", self.control,
                 *extra], stdout=self.log, stderr=subprocess.STDOUT)
            deadline = time.monotonic() + 10
            while not os.path.exists(self.control):
                assert self.proc.poll() is None, "ecat-sim exited: " + Path(self.log.name).read_text()
                assert time.monotonic() < deadline, "ecat-sim did not open its control socket"
                time.sleep(0.02)
        except BaseException:
            self.close()
            raise

    def probe(self, master, action, *args):
        r = subprocess.run(["ip", "netns", "exec", self.ns, sys.executable, str(PROBE), master, "ecm", action, *args],
                           capture_output=True, text=True, timeout=60)
        assert r.returncode == 0, f"probe {master} {action} failed:\n{r.stdout}\n{r.stderr}"
        return json.loads(r.stdout.strip().splitlines()[-1])

    def close(self):
        proc = getattr(self, "proc", None)
        if proc is not None and proc.poll() is None:
            proc.terminate()
            try:
                proc.wait(timeout=5)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
        sh("ip", "netns", "del", self.ns, check=False)
        if getattr(self, "log", None):
            self.log.close()
        self.tmp.cleanup()


@pytest.fixture
def segment():
    if os.geteuid() != 0:
        pytest.skip("needs root: network namespaces and raw sockets")
    s = Segment()
    yield s
    s.close()


@pytest.fixture
def plain_segment():
    """The segment without the safe terminals (`ecat-sim --no-safe-terminals`: as before issue 37)."""
    if os.geteuid() != 0:
        pytest.skip("needs root: network namespaces and raw sockets")
    s = Segment(extra=["--no-safe-terminals"])
    yield s
    s.close()


@pytest.fixture
def free_run_segment():
    """The drives also accept OP without DC SYNC0: kickcat's Python binding configures no
    distributed clocks (pysoem does, Soem.to_op)."""
    if os.geteuid() != 0:
        pytest.skip("needs root: network namespaces and raw sockets")
    s = Segment(extra=["--drives-free-run"])
    yield s
    s.close()


def test_pysoem_scans_identities_and_reaches_op(segment):
    r = segment.probe("soem", "scan")
    assert r["count"] == COUNT
    assert [i["vendor"] for i in r["identities"]] == [VENDOR] * COUNT
    assert [i["product"] for i in r["identities"]] == PRODUCTS
    assert [i["revision"] for i in r["identities"]] == [REVISION] * COUNT
    assert r["op"] is True
    assert r["wkc"] == r["expected_wkc"] == 28  # SOEM: 9 outputs x 2 + 10 inputs
    assert r["input_bytes"] == IN_BYTES
    assert r["ready"] is True
    assert all(sw & 0x4F == 0x40 for sw in r["statuswords"]), r["statuswords"]  # Switch on disabled
    # estop.a/b, gate.a/b closed, mode.auto; reduced.a/b (bits 18, 19, NC) and the field scanner's
    # OSSD pairs (bits 20..23, NC, clear) closed
    assert r["di"] == "8f00fc00"


def test_kickcat_scans_and_reaches_op_with_the_same_layout(free_run_segment):
    r = free_run_segment.probe("kick", "scan")
    assert r["count"] == COUNT
    assert r["op"] is True
    assert r["sizes"] == [[i, o] for i, o in zip(IN_BYTES, OUT_BYTES)]  # from the SII PDO categories
    assert r["ready"] is True
    assert all(sw & 0x4F == 0x40 for sw in r["statuswords"]), r["statuswords"]
    assert r["di"] == "8f00fc00"


def test_both_masters_read_the_same_statuswords(free_run_segment):
    a = free_run_segment.probe("soem", "scan")  # with DC (free run allowed, not required)
    b = free_run_segment.probe("kick", "scan")
    assert a["statuswords"] == b["statuswords"]
    assert a["di"] == b["di"]


def test_estop_on_one_channel_shows_on_the_wire(segment):
    r = segment.probe("soem", "estop", segment.control)
    assert r["answer"] == "OK"
    assert int(r["before"][0:2], 16) & 0x03 == 0x03
    assert int(r["after"][0:2], 16) & 0x03 == 0x01  # estop.b open, estop.a still closed


def test_contactor_output_and_cia402_walk_through_pdos(plain_segment):
    """The segment as before issue 37 (`--no-safe-terminals`): the DO terminal's bits drive K1
    and K2 (with the safe output terminal on the line only its containers do: below)."""
    r = plain_segment.probe("soem", "power")
    assert r["contactor_fb"] is True  # DO bit out, emulated contactor, DI feedback back
    assert r["k2_fb_with_k1_alone"] is False  # SPEC §14: K2 has its own output and its own contact
    assert r["contactor_fb_k2"] is True
    assert r["sequence"] == [True, True, True]  # Ready to switch on, Switched on, Operation enabled
    assert r["statusword"] & 0x6F == 0x27


def test_with_the_safe_output_terminal_the_do_bits_close_nothing(segment):
    """Issue 37: with the F-DO on the line K1 and K2 close only on valid containers of the
    channels; a master that sets the DO terminal's contactor bits closes nothing."""
    r = segment.probe("soem", "power")
    assert r["op"] is True
    assert r["contactor_fb"] is False and r["contactor_fb_k2"] is False
    st = json.loads(control(segment.control, "status"))
    assert st["safety"]["fdo"] == {"k1": False, "k2": False, "relay_a": False, "relay_b": False}
    assert st["safety"]["links"]["0xA002"]["state"] == "idle"  # nobody connected


def test_unplugged_drive_lowers_the_working_counter(segment):
    r = segment.probe("soem", "unplug", segment.control, "8")
    assert r["answer"] == "OK"
    assert r["wkc_before"] == r["expected_wkc"]
    # drive 6 neither read nor written (3), the sensor behind it not read (1), nor the F-DI and
    # F-DO (3 each)
    assert r["wkc_after"] == r["expected_wkc"] - 10


def test_pysoem_reads_and_writes_the_drives_sdos(segment):
    """Issue 22 item 4: an independent master uses the emulated drives' CoE mailbox."""
    r = segment.probe("soem", "sdo")
    assert r["vendor"] == VENDOR and r["product"] == PRODUCTS[2]
    assert r["name"] == "SafeState emu CiA402 CSP drive 1"
    assert r["torque_before"] == 1000 and r["torque_after"] == 1234
    assert r["aborts"] == {"read_only": 0x06010002, "range": 0x06090030, "length": 0x06070010,
                           "no_object": 0x06020000, "state": 0x08000022}, r["aborts"]
    assert r["op"] is True  # with 0x6060 = 8 written in PRE-OP
    st = json.loads(control(segment.control, "status"))
    assert st["sdo"][2]["6072:00"] == 1234 and st["sdo"][2]["6060:00"] == 8, st["sdo"]


def test_watchdog_drops_silent_outputs_to_safeop(segment):
    r = segment.probe("soem", "watchdog")
    al = r["al"]
    for pos in [*range(1, 8), 9, 10]:  # every subdevice with outputs (the safe terminals too)
        assert al[pos]["state"] == 0x14 and al[pos]["code"] == 0x1B, al
    assert al[0]["state"] == 0x08  # the input terminal has no output watchdog
    assert al[8]["state"] == 0x08  # nor has the distance sensor


def test_wrong_product_code_is_what_the_master_reads():
    if os.geteuid() != 0:
        pytest.skip("needs root")
    s = Segment(extra=["--product", "3=0x1234"])
    try:
        r = s.probe("soem", "scan")
        assert r["identities"][2]["product"] == 0x1234
        assert r["identities"][3]["product"] == PRODUCTS[3]
    finally:
        s.close()
