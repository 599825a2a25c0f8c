#!/usr/bin/env bash
# Self-test of tools/trace/traceability.py: on a copy of the repository it must pass, and it
# must fail, naming the requirement, when a requirement loses its last test, when a tag names
# an id that does not exist, when code loses its tag, and when the document is stale.
set -u
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
TOOL=$ROOT/tools/trace/traceability.py
DIR=$(mktemp -d)
trap 'rm -rf "$DIR"' EXIT
fails=0

fresh() {
  rm -rf "$DIR/r" && mkdir -p "$DIR/r"
  (cd "$ROOT" && tar --exclude='build*' --exclude=node_modules --exclude=.venv --exclude=.git -cf - \
     core motion controller hal sim scenario app runtime bridge gateway rta tools tests docs) | tar -C "$DIR/r" -xf -
}
expect() {  # expect NAME RC TEXT [--check]
  local name=$1 rc=$2 text=$3
  shift 3
  python3 "$TOOL" --root "$DIR/r" "$@" >"$DIR/out" 2>&1
  local got=$?
  if [[ $got -eq $rc ]] && grep -qF -- "$text" "$DIR/out"; then
    echo "ok   $name"
  else
    echo "FAIL $name: exit $got (want $rc), output:"; sed 's/^/     /' "$DIR/out"; fails=$((fails + 1))
  fi
}

fresh
expect "the repository as it is passes" 0 "all with code and tests" --check

fresh  # TR-C4b is tested by one unit test and one scenario: remove both tags
sed -i 's/^\/\/ @req TR-C4b$//' "$DIR/r/tests/unit/test_transitions.cpp"
sed -i 's/^# @req TR-C4b$//' "$DIR/r/tests/scenarios/row04b-gate-arming.scn"
expect "a requirement without a test fails" 1 "requirement TR-C4b has no test"

fresh
sed -i 's/^\/\/ @req RES-QUEUE-FULL$/\/\/ @req RES-QUEUE-FULLY/' "$DIR/r/tests/unit/test_commands.cpp"
expect "a tag naming an unknown id fails" 1 "@req names unknown requirement RES-QUEUE-FULLY"

fresh
sed -i '/@req RES-QUEUE-FULL/d' "$DIR/r/core/include/safestate/core/command_queue.hpp"
expect "a requirement without code fails" 1 "requirement RES-QUEUE-FULL has no code"

fresh
echo "| stale |" >>"$DIR/r/docs/traceability.md"
expect "a stale document fails the check" 1 "docs/traceability.md is stale" --check

if [[ $fails -ne 0 ]]; then
  echo "traceability_selftest: $fails check(s) failed"
  exit 1
fi
echo "traceability_selftest: all checks passed"
