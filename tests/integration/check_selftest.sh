#!/usr/bin/env bash
# The checker can fail: with a deliberately wrong invariant it must stop with exit 1 and
# write a counterexample that `safestate replay` reproduces (exit 1); with the real
# invariants it must pass.
set -euo pipefail
bin=${1:?usage: check_selftest.sh path/to/safestate}
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
set +e
"$bin" check --depth 2 --break-invariant --out "$dir" > "$dir/check.log"
rc=$?
set -e
[[ $rc -eq 1 ]] || { echo "check with a broken invariant exited $rc, expected 1"; cat "$dir/check.log"; exit 1; }
[[ -s "$dir/counterexample.scn" ]] || { echo "no counterexample written"; exit 1; }
grep -q "VIOLATION" "$dir/check.log" || { echo "no VIOLATION line"; exit 1; }
set +e
"$bin" replay "$dir/counterexample.scn" > "$dir/replay.log" 2>&1
rc=$?
set -e
[[ $rc -eq 1 ]] || { echo "replay of the counterexample exited $rc, expected 1 (it must reproduce)"; cat "$dir/counterexample.scn" "$dir/replay.log"; exit 1; }
echo "counterexample reproduced:"; cat "$dir/counterexample.scn"
"$bin" check --depth 1 --out "$dir" | tail -1
