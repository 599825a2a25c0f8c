#!/usr/bin/env bash
# The checker can fail: with a deliberately wrong invariant it must stop with exit 1 and
# write a counterexample that `safestate replay` reproduces (exit 1); with the real
# invariants it must pass.
set -euo pipefail
bin=${1:?usage: check_selftest.sh path/to/safestate}
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
# broken NAME WANT ARGS...: `check ARGS... --break-invariant` must stop with exit 1 at a violation
# whose line has WANT, write a counterexample, and `safestate replay` must reproduce it (exit 1).
broken() {
  local name=$1 want=$2
  shift 2
  rm -f "$dir/counterexample.scn"
  set +e
  "$bin" check "$@" --break-invariant --out "$dir" > "$dir/$name.log"
  local rc=$?
  set -e
  [[ $rc -eq 1 ]] || { echo "check $* with a broken invariant exited $rc, expected 1"; cat "$dir/$name.log"; exit 1; }
  [[ -s "$dir/counterexample.scn" ]] || { echo "check $*: no counterexample written"; exit 1; }
  grep -q "VIOLATION: .*$want" "$dir/$name.log" || { echo "check $*: no VIOLATION line with '$want'"; cat "$dir/$name.log"; exit 1; }
  set +e
  "$bin" replay "$dir/counterexample.scn" > "$dir/$name-replay.log" 2>&1
  rc=$?
  set -e
  [[ $rc -eq 1 ]] || { echo "replay of the counterexample of check $* exited $rc, expected 1 (it must reproduce)"; cat "$dir/counterexample.scn" "$dir/$name-replay.log"; exit 1; }
  echo "counterexample of check $* reproduced:"; cat "$dir/counterexample.scn"
}

broken check "E-stop pressed => IDLE" --depth 2
"$bin" check --depth 1 --out "$dir" | tail -1

# SPEC §14 (--pair): with one channel frozen the other must open its contactor within
# cross_check_cycles + 1 cycles; asked for one cycle (--break-invariant), the checker must find
# a powered configuration where that fails, and the counterexample must reproduce in replay.
broken pair "one channel frozen (channel A stall)" --pair --depth 1
grep -q "fault channel A stall" "$dir/counterexample.scn" || { echo "the counterexample does not freeze a channel"; cat "$dir/counterexample.scn"; exit 1; }
out=$("$bin" check --pair --depth 2 --out "$dir")
echo "$out" | tail -2
echo "$out" | grep -q "all invariants hold" || { echo "check --pair --depth 2 failed"; exit 1; }
echo "$out" | grep -Eq "the pair \(SPEC 14\): [1-9][0-9]* runs with one channel frozen" || { echo "no frozen runs"; exit 1; }
