#!/usr/bin/env bash
# Builds core/, motion/, safelink/ (the black channel's layer) and controller/ for a Cortex-M4F (arm-none-eabi, newlib-nano), links a bare-
# metal image around the supervisor, and proves what DESIGN.md promises: no heap, no
# exceptions, no RTTI. Prints .text/.data/.bss per library into build-m4/size.txt.
set -euo pipefail
cd "$(dirname "$0")/../.."
out=build-m4
rm -rf "$out" && mkdir -p "$out/core" "$out/motion" "$out/safelink" "$out/controller"

CXX=arm-none-eabi-g++
FLAGS=(-std=c++20 -mcpu=cortex-m4 -mthumb -mfloat-abi=hard -mfpu=fpv4-sp-d16 -Os
       -fno-exceptions -fno-rtti -fno-threadsafe-statics -ffunction-sections -fdata-sections
       -Wall -Wextra -Wconversion -Wdouble-promotion -Werror -Icore/include -Imotion/include -Ihal/include
       -Isafelink/include -Icontroller/include)

for f in core/src/*.cpp core/src/monitors/*.cpp; do
  "$CXX" "${FLAGS[@]}" -c "$f" -o "$out/core/$(basename "${f%.cpp}").o"
done
for lib in motion safelink controller; do
  for f in "$lib"/src/*.cpp; do
    "$CXX" "${FLAGS[@]}" -c "$f" -o "$out/$lib/$(basename "${f%.cpp}").o"
  done
done
"$CXX" "${FLAGS[@]}" -c tools/embedded/main.cpp -o "$out/main.o"
"$CXX" "${FLAGS[@]}" --specs=nano.specs --specs=nosys.specs -Wl,--gc-sections -Wl,-Map="$out/image.map" \
  "$out/main.o" "$out"/controller/*.o "$out"/safelink/*.o "$out"/motion/*.o "$out"/core/*.o -lm -o "$out/image.elf"

# Nothing that allocates or throws may be linked into the image.
forbidden='^(malloc|_malloc_r|calloc|realloc|free|_free_r|_ZdlPv|_ZdlPvj|_ZdaPv|_ZdaPvj|_Znwj|_Znaj|_Znwm|_Znam|__cxa_allocate_exception|__cxa_throw|__gxx_personality_v0|_ZTI.*|_ZTS.*)$'
if arm-none-eabi-nm "$out/image.elf" | awk '{print $NF}' | grep -E "$forbidden" > "$out/forbidden.txt"; then
  echo "embedded: the image links heap / exception / RTTI symbols:" >&2
  cat "$out/forbidden.txt" >&2
  exit 1
fi

section_sum() {  # $1: section column (text|data|bss), rest: objects
  local col=$1; shift
  arm-none-eabi-size "$@" | awk -v c="$col" 'NR>1 {t += $c} END {print t+0}'
}
{
  echo "Cortex-M4F (arm-none-eabi-g++ $("$CXX" -dumpversion), -Os, -fno-exceptions -fno-rtti)"
  printf '%-8s %8s %8s %8s\n' lib .text .data .bss
  for lib in core motion safelink controller; do
    objs=("$out/$lib"/*.o)
    [[ -e "${objs[0]}" ]] || continue
    printf '%-8s %8s %8s %8s\n' "$lib" "$(section_sum 1 "${objs[@]}")" "$(section_sum 2 "${objs[@]}")" "$(section_sum 3 "${objs[@]}")"
  done
  echo
  echo "linked image (the whole scan cycle: supervisor + motion + newlib-nano start-up and libm):"
  arm-none-eabi-size "$out/image.elf"
} | tee "$out/size.txt"
echo "embedded: OK (no heap, exception or RTTI symbols in the image)"
