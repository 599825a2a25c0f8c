#!/usr/bin/env bash
# Cortex-M4 instructions per scan cycle, with and without the SPEC §10 monitors: builds
# tools/embedded/bench_m4.cpp with the flags of embedded.sh (-Os, Cortex-M4F, no exceptions,
# no RTTI) for five configurations (0: monitors not configured, the landed baseline; 1: no
# zone; 2: sixteen zones and an orientation cone; 3: as 2 with every zone tested every cycle;
# 4: as 1 with the SPEC §14 cross-check after every cycle)
# and two lengths each, runs every image in
# QEMU's mps2-an386 (a Cortex-M4F board) one instruction per block with the execution log
# on, and counts the instructions executed. (long - short) / (cycles between) is the cost
# of one cycle, start-up excluded. Prints JSON on stdout; bench/run.py records it.
set -euo pipefail
cd "$(dirname "$0")/../.."
out=build-m4-bench
rm -rf "$out" && mkdir -p "$out/obj"
CXX=arm-none-eabi-g++
FLAGS=(-std=c++20 -mcpu=cortex-m4 -mthumb -mfloat-abi=hard -mfpu=fpv4-sp-d16 -Os
       -fno-exceptions -fno-rtti -fno-threadsafe-statics -ffunction-sections -fdata-sections
       -Wall -Wextra -Wconversion -Wdouble-promotion -Werror -Icore/include -Imotion/include -Ihal/include
       -Isafelink/include -Icontroller/include)
SHORT=${M4_SHORT:-20}
LONG=${M4_LONG:-60}
for f in core/src/*.cpp core/src/monitors/*.cpp motion/src/*.cpp safelink/src/*.cpp controller/src/*.cpp; do
  # Named by path: core/src/monitors/channels.cpp and controller/src/channels.cpp are two files.
  "$CXX" "${FLAGS[@]}" -c "$f" -o "$out/obj/$(echo "${f%.cpp}" | tr / _).o" &
  while (( $(jobs -rp | wc -l) >= 2 )); do wait -n; done
done
wait
count() {  # $1 limits mode, $2 cycles: instructions executed by the whole image
  local img="$out/bench-$1-$2.elf"
  "$CXX" "${FLAGS[@]}" -DBENCH_LIMITS="$1" -DBENCH_CYCLES="$2" -c tools/embedded/bench_m4.cpp -o "$img.o"
  "$CXX" "${FLAGS[@]}" -nostartfiles -T tools/embedded/bench_m4.ld --specs=nano.specs --specs=nosys.specs \
    -Wl,--gc-sections "$img.o" "$out"/obj/*.o -lm -o "$img"
  timeout 300 qemu-system-arm -M mps2-an386 -cpu cortex-m4 -nographic -monitor none -serial none \
    -semihosting-config enable=on,target=native -kernel "$img" -singlestep -d exec,nochain -D /dev/stdout \
    | grep -c '^Trace'
}
declare -A per
for mode in 0 1 2 3 4; do
  a=$(count "$mode" "$SHORT")
  b=$(count "$mode" "$LONG")
  per[$mode]=$(( (b - a) / (LONG - SHORT) ))
done
printf '{"compiler": "arm-none-eabi-g++ %s -Os", "qemu": "%s", "cycles": [%d, %d], "baseline": %d, "zones0": %d, "zones16": %d, "zones16_all": %d, "crosscheck": %d}\n' \
  "$("$CXX" -dumpversion)" "$(qemu-system-arm --version | head -1)" "$SHORT" "$LONG" "${per[0]}" "${per[1]}" "${per[2]}" "${per[3]}" "${per[4]}"
