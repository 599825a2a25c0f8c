#!/usr/bin/env python3
"""Nothing of the simulator is in the loop of `safestate run --fieldbus ethercat` (issue 35 item 3).

The controller, the real-time loop, `safestate run` and the gateway reach the simulated cell
only through the backend factory (backends/factory.hpp): their objects must neither define
nor use a symbol of namespace safestate::sim, and their sources must not include sim/. The
factory's own archive must use sim (else this check could not fail: the self-test).

    no_sim_in_the_loop.py BUILD_LIB_DIR SOURCE_ROOT
Exit 0 when clean; 1 naming each object and symbol (or source and include) that is not.
"""
import pathlib
import re
import subprocess
import sys

LOOP = ["safestate_controller", "safestate_rt", "safestate_runtime", "safestate_gateway", "safestate_hal_ethercat",
        "safestate_bridge", "safestate_vocab"]
FACTORY = "safestate_backends"
SOURCES = ["controller", "runtime", "gateway", "bridge", "hal", "vocab", "rta"]
SIM = re.compile(r"\bsafestate::sim::")


def sim_symbols(archive):
    out = subprocess.run(["nm", "-C", "-A", str(archive)], check=True, capture_output=True, text=True).stdout
    return [line for line in out.splitlines() if SIM.search(line)]


def main():
    if len(sys.argv) != 3:
        raise SystemExit(__doc__)
    lib, root = pathlib.Path(sys.argv[1]), pathlib.Path(sys.argv[2])
    bad = []
    for name in LOOP:
        a = lib / f"lib{name}.a"
        if not a.exists():
            raise SystemExit(f"no_sim_in_the_loop: {a} not built")
        bad += [f"{name}: {line}" for line in sim_symbols(a)]
    include = re.compile(r'#include\s+[<"]safestate/sim/')
    for d in SOURCES:
        for f in sorted((root / d).rglob("*.[ch]pp")):
            if d == "hal" and "ethercat" not in f.parts and "include" not in f.parts:
                continue
            for n, text in enumerate(f.read_text(errors="replace").splitlines(), 1):
                if include.search(text):
                    bad.append(f"{f.relative_to(root)}:{n}: {text.strip()}")
    factory = sim_symbols(lib / f"lib{FACTORY}.a")
    if not factory:
        bad.append(f"self-test: lib{FACTORY}.a uses no safestate::sim symbol, so this check could not see one")
    for b in bad[:50]:
        print(b)
    if bad:
        print(f"no_sim_in_the_loop: {len(bad)} finding(s): the loop must reach sim/ only through the backend factory")
        return 1
    print(f"no_sim_in_the_loop: {len(LOOP)} archives and the sources of {', '.join(SOURCES)} are free of sim/; "
          f"the factory uses it ({len(factory)} symbol references)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
