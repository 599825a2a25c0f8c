#!/usr/bin/env bash
# `make bench-check`: the exhaustive checker deeper than `safestate check`'s default (depth 4,
# a few minutes) and `make test`'s (depth 3): depth 5 by default (CHECK_DEPTH), every
# invariant and the reference after every cycle. Prints the checker's summary, the wall time
# and the peak memory (GNU time); docs/verification.md reports the figures. A violation
# leaves its counterexample in build/check-deep/counterexample.scn (exit 1).
set -euo pipefail
cd "$(dirname "$0")/.."
depth=${CHECK_DEPTH:-5}
max=${CHECK_MAX_CONFIGS:-200000}
out=build/check-deep
mkdir -p "$out"
bin=$PWD/build/bin/safestate
echo "safestate check --depth $depth --max-configs $max ($(nproc) cores, $(date -u '+%Y-%m-%d %H:%M UTC'))"
if [ -x /usr/bin/time ]; then
  /usr/bin/time -f 'wall %e s, peak memory %M kB' "$bin" check --depth "$depth" --max-configs "$max" -v --out "$out"
else
  t0=$SECONDS
  "$bin" check --depth "$depth" --max-configs "$max" -v --out "$out"
  echo "wall $((SECONDS - t0)) s"
fi
