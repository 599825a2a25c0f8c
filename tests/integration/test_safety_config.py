"""The safety configuration outside the core (SPEC §10), end to end through `safestate safety`.

- Differential: our RFC 8785 form against PyPI's rfc8785 (Trail of Bits) on random JSON
  (fixed seed): floats from random IEEE-754 bit patterns, integers within ±2^53, strings
  with control characters, non-ASCII and astral characters in values and keys.
- `safestate safety check`: the checksum it prints is the one anybody computes from the
  file with rfc8785 + hashlib (SPEC §10 "Checksum"); exit 0 valid, 2 with every error named.
"""
import hashlib
import json
import math
import os
import random
import struct
import subprocess
from pathlib import Path

import rfc8785

BIN = os.environ["SAFESTATE_BIN"]
ROOT = Path(__file__).resolve().parents[2]


def safestate(*args):
    return subprocess.run([BIN, *args], capture_output=True, text=True, encoding="utf-8", timeout=30)


def random_string(rng, max_len=8):
    out = []
    for _ in range(rng.randrange(max_len + 1)):
        pick = rng.random()
        if pick < 0.15:
            out.append(chr(rng.randrange(0x20)))  # control characters
        elif pick < 0.25:
            out.append(rng.choice('"\\/\x7f'))
        elif pick < 0.55:
            out.append(chr(rng.randrange(0x20, 0x7F)))
        elif pick < 0.8:
            cp = rng.randrange(0x80, 0x10000)
            out.append(chr(cp) if not 0xD800 <= cp < 0xE000 else "\ufb33")
        else:
            out.append(chr(rng.randrange(0x10000, 0x110000)))  # astral: a surrogate pair in UTF-16
    return "".join(out)


def random_float(rng):
    while True:
        pick = rng.random()
        if pick < 0.6:
            x = struct.unpack("<d", struct.pack("<Q", rng.getrandbits(64)))[0]
        elif pick < 0.8:
            x = rng.uniform(-1e6, 1e6)
        else:
            x = rng.randrange(-10**6, 10**6) / 10 ** rng.randrange(8)
        if math.isfinite(x):
            return x


def random_value(rng, depth=0):
    pick = rng.random()
    if depth < 4 and pick < 0.2:
        return {random_string(rng, 4): random_value(rng, depth + 1) for _ in range(rng.randrange(6))}
    if depth < 4 and pick < 0.35:
        return [random_value(rng, depth + 1) for _ in range(rng.randrange(6))]
    if pick < 0.6:
        return random_float(rng)
    if pick < 0.75:
        return rng.randrange(-(2**53) + 1, 2**53)
    if pick < 0.9:
        return random_string(rng)
    return rng.choice([None, True, False])


def canonical_by_safestate(tmp_path, doc, ensure_ascii):
    f = tmp_path / "doc.json"
    f.write_text(json.dumps(doc, ensure_ascii=ensure_ascii, indent=1), encoding="utf-8")
    r = subprocess.run([BIN, "safety", "canonical", str(f)], capture_output=True, timeout=30)
    assert r.returncode == 0, r.stderr
    assert r.stdout.endswith(b"\n")
    return r.stdout[:-1]


def test_canonical_form_matches_rfc8785_on_random_json(tmp_path):
    rng = random.Random(8785)
    docs = [{random_string(rng, 4): random_value(rng) for _ in range(rng.randrange(1, 8))} for _ in range(2000)]
    for ensure_ascii in (True, False):  # \uXXXX escapes in the input and raw UTF-8
        ours = canonical_by_safestate(tmp_path, docs, ensure_ascii)
        theirs = rfc8785.dumps(docs)
        if ours != theirs:
            for d in docs:  # name the first document that differs
                one = canonical_by_safestate(tmp_path, d, ensure_ascii)
                assert one == rfc8785.dumps(d), f"input {d!r}"
            assert ours == theirs


def test_rfc_vectors_through_the_command(tmp_path):
    # RFC 8785 §3.2.2 through the binary (the unit test checks the library).
    f = tmp_path / "ex.json"
    f.write_text('{"numbers": [333333333.33333329, 1E30, 4.50, 2e-3, 0.000000000000000000000000001],'
                 '"string": "\\u20ac$\\u000F\\u000aA\'\\u0042\\u0022\\u005c\\\\\\"\\/",'
                 '"literals": [null, true, false]}')
    r = safestate("safety", "canonical", str(f))
    assert r.returncode == 0, r.stderr
    assert r.stdout == ('{"literals":[null,true,false],"numbers":[333333333.3333333,1e+30,4.5,0.002,1e-27],'
                        '"string":"€$\\u000f\\nA\'B\\"\\\\\\\\\\"/"}\n')


def checksum_of(path):
    # SPEC §10 / docs/safety-configuration.md: what an integrator computes by hand.
    return hashlib.sha256(rfc8785.dumps(json.loads(Path(path).read_bytes()))).hexdigest()[:8].upper()


def test_check_prints_the_independent_checksum_and_exits_0():
    for name in ("cell.json", "collaborative.json"):
        path = ROOT / "examples" / "safety" / name
        r = safestate("safety", "check", str(path))
        assert r.returncode == 0, r.stdout + r.stderr
        assert f"checksum:  {checksum_of(path)}\n" in r.stdout
        assert "table keep_out [250, -350, -400] .. [700, 350, 50] mm" in r.stdout
        assert "stop:      within 800 ms" in r.stdout
    r = safestate("safety", "check", "--default")
    assert r.returncode == 0, r.stdout
    assert "zones:     0 (none)" in r.stdout and "tcp speed: 2000 mm/s" in r.stdout


def test_check_lists_every_error_and_exits_2(tmp_path):
    doc = json.loads((ROOT / "examples" / "safety" / "cell.json").read_text())
    doc["joints"][2]["max_deg"] = "70"
    doc["zones"][1]["name"] = "table"
    doc["reduced"]["tcp_max_speed_mm_s"] = 1600
    del doc["stop"]
    doc["tool"]["mass_kg"] = 1
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(doc))
    r = safestate("safety", "check", str(bad))
    assert r.returncode == 2, r.stdout
    for line in ("joints[2].max_deg: must be a number (found a string)",
                 'zones[1].name: duplicate zone name "table" (also zones[0].name)',
                 "reduced.tcp_max_speed_mm_s: must be <= tcp_max_speed_mm_s (1500)",
                 "stop: missing (required)",
                 "tool.mass_kg: unknown key"):
        assert line in r.stdout, r.stdout
    assert f"{bad}: 5 errors" in r.stdout
    assert "checksum" not in r.stdout  # no checksum of a refused file


def test_check_refuses_a_file_over_1_mib_and_bad_usage(tmp_path):
    big = tmp_path / "big.json"
    big.write_bytes(b"{" + b" " * (1024 * 1024) + b"}")
    r = safestate("safety", "check", str(big))
    assert r.returncode == 2 and "larger than 1048576 bytes" in r.stdout, r.stdout
    assert safestate("safety", "check").returncode == 2
    r = safestate("safety", "check", str(tmp_path / "missing.json"))
    assert r.returncode == 2 and "no such file" in r.stdout
