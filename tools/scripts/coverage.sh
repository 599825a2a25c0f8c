#!/usr/bin/env bash
# Source-based coverage (clang-19) with MC/DC over core/ and motion/, from the unit
# tests, the scenario suite and the exhaustive checker. Writes build-cov/coverage.txt
# (the llvm-cov report), build-cov/mcdc-gaps.txt (the conditions not covered) and
# build-cov/html/ (annotated sources); fails if MC/DC fell below docs/mcdc-baseline.txt.
set -euo pipefail
cd "$(dirname "$0")/../.."
cmake --preset coverage > /dev/null
cmake --build --preset coverage
prof=build-cov/profiles
rm -rf "$prof" && mkdir -p "$prof"
export LLVM_PROFILE_FILE="$PWD/$prof/%p-%m.profraw"
# Everything that exercises core/ and motion/ in-process (not the gateway, OPC UA, EtherCAT,
# HMI or C# processes, valgrind, the M4 build or the browser): the figures then depend
# neither on the venv, node or dotnet being installed nor on timing, and are the same on
# every run, which the baseline check below needs. (mcdc_docs: that check is the last
# step here.)
ctest --test-dir build-cov -j2 -E '^(gateway_|opcua_|ecat_|hmi_|csharp_|mcdc_docs)|alloc_per_cycle|embedded_m4|runner_selftest|check_selftest|demo_story' \
  --output-on-failure > build-cov/ctest.log || { tail -30 build-cov/ctest.log; exit 1; }
llvm-profdata-19 merge -sparse "$prof"/*.profraw -o build-cov/merged.profdata
objects=()
for b in build-cov/bin/test_* build-cov/bin/safestate; do objects+=(-object "$b"); done
sources=(core/src core/include motion/src motion/include)
llvm-cov-19 report -instr-profile build-cov/merged.profdata "${objects[@]:1}" --show-mcdc-summary \
  "${sources[@]}" > build-cov/coverage.txt
llvm-cov-19 show -instr-profile build-cov/merged.profdata "${objects[@]:1}" --show-mcdc --format=html \
  -output-dir build-cov/html "${sources[@]}" > /dev/null
cat build-cov/coverage.txt
# The conditions whose independence pair no test shows (docs/verification.md explains each).
llvm-cov-19 show -instr-profile build-cov/merged.profdata "${objects[@]:1}" --show-mcdc "${sources[@]}" \
  | python3 tools/scripts/mcdc_gaps.py > build-cov/mcdc-gaps.txt
# MC/DC may not go down: fails on a file below docs/mcdc-baseline.txt, or on stale figures
# (then tools/scripts/mcdc.py --update, and a bullet in docs/verification.md for every
# condition that cannot be covered).
python3 tools/scripts/mcdc.py --compare build-cov/coverage.txt
