#!/usr/bin/env python3
"""`safestate ecat-config` end to end (issue 22 item 5): the shipped ESI makes a bus
configuration that `safestate rta --bus-config` accepts, with the built-in one's content;
bad input exits 2 naming the file, the line and the element, and writes nothing.
Usage: ecat_config_cli.py SAFESTATE_BIN SOURCE_DIR"""
import json
import os
import subprocess
import sys
import tempfile

BIN, SRC = sys.argv[1], sys.argv[2]
ESI = os.path.join(SRC, "hal/ethercat/esi/SafeState-Emulated.xml")
ORDER = ["--device", "0x00D10018", "--device", "0x00D00003", "--device", "0x00402001*6", "--device", "0x00D15001"]
failures = []


def run(*args):
    p = subprocess.run([BIN, "ecat-config", *args], capture_output=True, text=True, timeout=60)
    return p.returncode, p.stdout, p.stderr


def check(cond, what):
    if not cond:
        failures.append(what)
        print("FAIL:", what)


with tempfile.TemporaryDirectory() as tmp:
    out = os.path.join(tmp, "bus.json")
    rc, so, se = run("--esi", ESI, *ORDER, "--counts-per-rev", "1048576", "--out", out)
    check(rc == 0, f"shipped ESI: exit {rc}, stderr {se!r}")
    check("9 subdevices written to" in se, f"shipped ESI: stderr {se!r}")
    with open(out) as f:
        got = json.load(f)
    with open(os.path.join(SRC, "hal/ethercat/default-bus.json")) as f:
        want = json.load(f)
    check(len(got["subdevices"]) == 9, "9 subdevices")
    # SPEC §11's distance sensor is found by its entry names; the DO's reduced_active bit too.
    check(got["subdevices"][8]["role"] == "distance_sensor", f"distance sensor: {got['subdevices'][8]}")
    check(got["subdevices"][1]["bits"].get("reduced_active") == 9, f"reduced_active: {got['subdevices'][1]['bits']}")
    for g, w in zip(got["subdevices"], want["subdevices"]):
        for key in ("role", "vendor_id", "product_code", "in_bytes", "out_bytes", "bits", "axis", "pdo",
                    "counts_per_revolution"):
            check(g.get(key) == w.get(key), f"{w['name']}.{key}: {g.get(key)!r} != {w.get(key)!r}")
        # Start-up values: the same bytes (the ESI's <Data> is unsigned: -3 is 253 in one byte).
        gs = [(int(e["index"], 16), e["sub"], e["size"], e["value"] % (1 << (8 * e["size"]))) for e in g.get("startup", [])]
        ws = [(int(e["index"], 16), e["sub"], e["size"], e["value"] % (1 << (8 * e["size"]))) for e in w.get("startup", [])]
        check(gs == ws, f"{w['name']}.startup: {gs} != {ws}")
        check(g.get("dc") == ({"assign_activate": "0x0300"} if g["role"] == "drive" else None), f"{w['name']}.dc")
    # The backend's own reader takes it (rta reads the bus configuration with parse_bus_config).
    p = subprocess.run([BIN, "rta", "--bus-config", out], capture_output=True, text=True, timeout=60)
    check(p.returncode == 0, f"rta --bus-config: exit {p.returncode}, {p.stderr!r}")
    # SPEC §11: a bus without the distance sensor is a bus (the sensor is optional), and the
    # analysis says what SSM then does; with it, it says nothing of the kind.
    collab = os.path.join(SRC, "examples/safety/collaborative.json")
    no_sensor = os.path.join(tmp, "no-sensor.json")
    with open(no_sensor, "w") as f:
        json.dump({**got, "subdevices": [s for s in got["subdevices"] if s["role"] != "distance_sensor"]}, f)
    note = "the bus configuration has no distance_sensor"
    for path, has in ((out, False), (no_sensor, True)):
        p = subprocess.run([BIN, "rta", "--bus-config", path, "--safety", collab], capture_output=True, text=True,
                           timeout=60)
        check(p.returncode == 0 and (note in p.stdout) == has, f"rta --bus-config {path}: {p.returncode} {p.stderr!r}")

    # One drive with another encoder: AXIS=N beside the resolution of the others.
    rc, so, se = run("--esi", ESI, *ORDER, "--counts-per-rev", "1048576", "3=4096")
    check(rc == 0, f"3=4096: exit {rc} {se!r}")
    if rc == 0:
        cpr = [s.get("counts_per_revolution") for s in json.loads(so)["subdevices"]]
        check(cpr == [None, None, 1048576, 1048576, 4096, 1048576, 1048576, 1048576, None], f"3=4096: {cpr}")

    # Standard output without --out.
    rc, so, se = run("--esi", ESI, *ORDER, "--counts-per-rev", "1048576")
    check(rc == 0 and json.loads(so)["subdevices"][2]["name"] == "drive axis 1", f"stdout: exit {rc} {se!r}")

    # Bad input: exit 2, the message names what is wrong, the existing --out is untouched.
    with open(ESI) as f:
        text = f.read()
    before = open(out).read()

    def bad(name, content, *extra, expect):
        path = os.path.join(tmp, name)
        with open(path, "w") as f:
            f.write(content)
        rc, so, se = run("--esi", path, *ORDER, "--counts-per-rev", "1048576", "--out", out, *extra)
        check(rc == 2, f"{name}: exit {rc} (expected 2), stderr {se!r}")
        check(expect.replace("FILE", path) in se, f"{name}: {expect!r} not in {se!r}")
        check(open(out).read() == before, f"{name}: --out was changed")
        check(so == "", f"{name}: printed {so!r}")

    line = text[: text.index("<BitLen>32</BitLen><Name>Velocity")].count("\n") + 1
    bad("bitlen.xml", text.replace("<BitLen>32</BitLen><Name>Velocity", "<BitLen>16</BitLen><Name>Velocity"),
        expect=f"FILE:{line}: <Device> \"SS-EMU-CSP\" <TxPdo> 0x1A00 <Entry> 3 (0x606C:0 \"Velocity actual value\"): "
               "<BitLen> 16 does not match <DataType> DINT (32 bits)")
    bad("notxml.xml", text[:400], expect="FILE:")
    bad("notxml2.xml", "not xml at all", expect="not well-formed XML")
    bad("noid.xml", text.replace("<Id>#x00005AFE</Id>", ""), expect="missing <Vendor><Id>")
    bad("noproduct.xml", text.replace('ProductCode="#x00402001" ', ""), expect="missing <Type ProductCode>")
    bad("type.xml", text.replace("<DataType>UINT</DataType>", "<DataType>WHATEVER</DataType>", 1),
        expect="unknown or unsupported <DataType> \"WHATEVER\"")
    bad("initcmd.xml", text.replace("<Data>e803</Data>", "<Data>e80300000000</Data>"),
        expect="<Data>: 6 bytes; the master writes 1, 2 or 4 bytes")
    nt = text.replace("<Entry><Index>#x6077</Index><SubIndex>0</SubIndex><BitLen>16</BitLen><Name>Torque actual value</Name>"
                      "<DataType>INT</DataType></Entry>", "")
    bad("no6077.xml", nt, expect="has no 0x6077 (torque_actual)")
    bad("sensor16.xml", text.replace("<BitLen>32</BitLen><Name>separation_mm</Name><DataType>DINT</DataType>",
                                      "<BitLen>16</BitLen><Name>separation_mm</Name><DataType>INT</DataType>"),
        expect="separation_mm is 16 bits at bit 0 (INT); expected a 32-bit DINT on a byte boundary")
    bad("sensorvalid.xml", text.replace("<Name>separation_valid</Name>", "<Name>Status</Name>"),
        expect="a distance sensor's TxPDO needs both separation_mm and separation_valid; it lacks separation_valid")
    # Arguments.
    for args, expect in [((), "give the ESI files with --esi"),
                         (("--esi", ESI, "--counts-per-rev", "1048576"), "give the bus order"),
                         (("--esi", ESI, "--device", "0x00402001*6"), "give --counts-per-rev N"),
                         (("--esi", ESI, "--device", "0x99"), "--device 0x99: no device of the ESI files"),
                         (("--esi", ESI, ESI, "--device", "0x00D10018"), "is already described at " + ESI),
                         (("--esi", ESI, *ORDER, "--counts-per-rev", "0"), "--counts-per-rev 0: expected N or AXIS=N"),
                         (("--esi", ESI, *ORDER, "--counts-per-rev", "x=4"), "--counts-per-rev x=4: expected N or AXIS=N"),
                         (("--esi", ESI, *ORDER, "--counts-per-rev", "4096", "2=1", "2=8"), "axis 2 is given twice"),
                         (("--esi", ESI, *ORDER, "--counts-per-rev", "4096", "9=1"), "there is no drive axis 9"),
                         (("--esi", os.path.join(tmp, "missing.xml"), "--device", "0x1"), "missing.xml: cannot read the file"),
                         (("--esi", ESI, "--device", "0x00D10018", "--counts-per-rev", "1048576"),
                          "the configuration made from these devices is refused: subdevices: no drive for axis 1")]:
        rc, so, se = run(*args, "--out", out)
        check(rc == 2, f"{args}: exit {rc}")
        check(expect in se, f"{args}: {expect!r} not in {se!r}")
        check(open(out).read() == before, f"{args}: --out was changed")
    check(not [n for n in os.listdir(tmp) if ".tmp." in n], "a temporary file was left behind")

print("ecat_config_cli:", "FAILED " + str(len(failures)) if failures else "ok")
sys.exit(1 if failures else 0)
