#!/usr/bin/env bash
# Runs the C# client's NUnit 2.6 tests (unit tests, a stub server, and a real
# `safestate run` on free loopback ports) and prints the plain summary line
# `N passed, N failed`. Usage: clients/csharp/run-tests.sh [--build] [NUnit -run=NAME]
# (--build: run build.sh first). SAFESTATE_BIN points at the safestate binary (default
# build/bin/safestate).
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
for tool in mono mcs nunit-console; do
  command -v "$tool" >/dev/null || { echo "csharp: $tool not found; run \`make csharp\` (installs Mono and NUnit)" >&2; exit 1; }
done
if [[ "${1:-}" == "--build" ]]; then
  shift
  "$here/build.sh"
fi
export SAFESTATE_BIN="${SAFESTATE_BIN:-$here/../../build/bin/safestate}"
out="$(mktemp -d)"
trap 'rm -rf "$out"' EXIT
status=0
# -nothread: tests run on the runner's own thread (no extra STA/MTA thread); -noshadow: load
# the assemblies in place so the tests find SafeState.Console.exe beside them.
nunit-console "$here/bin/SafeState.Tests.dll" -nologo -noshadow -nothread -labels -xml="$out/result.xml" "$@" \
  >"$out/log.txt" 2>&1 || status=$?
if [[ ! -s "$out/result.xml" ]]; then
  cat "$out/log.txt"
  echo "0 passed, 1 failed (nunit-console produced no result, exit $status)"
  exit 1
fi
python3 - "$out/result.xml" "$out/log.txt" <<'PY'
import sys, xml.etree.ElementTree as ET
root = ET.parse(sys.argv[1]).getroot()
cases = root.iter("test-case")
passed = failed = 0
failures = []
for c in cases:
    if c.get("executed") != "True":
        continue
    if c.get("success") == "True":
        passed += 1
    else:
        failed += 1
        msg = c.find("./failure/message")
        failures.append(f"FAILED {c.get('name')}: {(msg.text or '').strip() if msg is not None else c.get('result')}")
if failed:
    print(open(sys.argv[2], errors="replace").read()[-20000:])
    print("\n".join(failures))
print(f"{passed} passed, {failed} failed")
sys.exit(1 if failed or passed == 0 else 0)
PY
