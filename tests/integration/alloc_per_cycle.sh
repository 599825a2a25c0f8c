#!/usr/bin/env bash
# Nothing allocates per cycle: two replays that differ only in length (program running
# in both, the simulated person walking and seen by its scanner and distance sensor in
# both) must make exactly the same number of heap allocations under valgrind.
set -euo pipefail
bin=${1:?usage: alloc_per_cycle.sh path/to/safestate}
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
write() {  # $1 file, $2 last cycle
  cat > "$1" <<SCN
@0    person at 4000 0
@100  cmd reset
@110  cmd servo_on
@400  cmd start
@400  person walk 4000 3000 1000 -4000 3000 1000 stand 100 -4000 -3000 1000
@$2 expect sub=AUTO_RUNNING
SCN
}
write "$dir/short.scn" 1500
write "$dir/long.scn"  4500
allocs() {
  valgrind --tool=memcheck --error-exitcode=3 "$bin" replay "$1" 2>&1 >/dev/null |
    sed -n 's/.*total heap usage: \([0-9,]*\) allocs.*/\1/p' | tr -d ,
}
a=$(allocs "$dir/short.scn")
b=$(allocs "$dir/long.scn")
echo "heap allocations: 1501 cycles: $a, 4501 cycles: $b"
[[ -n "$a" && -n "$b" ]] || { echo "could not read valgrind's totals" >&2; exit 1; }
[[ "$a" == "$b" ]] || { echo "allocation count depends on run length: something allocates per cycle" >&2; exit 1; }
