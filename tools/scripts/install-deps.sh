#!/usr/bin/env bash
# Installs, once, only the Debian packages that are missing. Usage: install-deps.sh GROUP...
# Groups: build (compilers: g++ and clang-19, which builds channel B of SPEC §14; CMake, GoogleTest; Orocos KDL for the simulated arm's dynamics; pugixml for ESI files),
# embedded (Cortex-M4 toolchain), lint (clang-tidy, cppcheck), bench (Google Benchmark, callgrind, cyclictest),
# browser (Debian's Chromium for the HMI's browser tests; Node.js >= 20.19 is expected on
# the machine: Debian 12's nodejs is too old for Vite),
# csharp (Mono 6.8 and NUnit 2.6 for clients/csharp; no NuGet), ecat (ip: network namespaces and
# veth pairs for the EtherCAT tests; cargo comes from rustup, Debian 12's is too old for ethercrab),
# ros2 (a venv for ROS 2 Jazzy's PyPI wheels, built for CPython 3.11 = Debian 12's python3, and
# what compiles the generated safestate_msgs: CMake, Ninja, a C/C++ compiler, Python's headers).
set -euo pipefail

declare -A GROUPS_PKGS=(
  [build]="g++ clang-19 cmake ninja-build make libgtest-dev libgmock-dev libcli11-dev nlohmann-json3-dev libboost-dev libsqlite3-dev libssl-dev liborocos-kdl-dev liburdfdom-dev libpugixml-dev valgrind python3"
  [fuzz]="clang-19 llvm-19 libclang-rt-19-dev"
  [python]="python3 python3-venv python3-pip"
  [embedded]="gcc-arm-none-eabi libstdc++-arm-none-eabi-newlib libnewlib-arm-none-eabi binutils-arm-none-eabi"
  [browser]="chromium"
  [lint]="clang-tidy-19 cppcheck"
  [bench]="libbenchmark-dev valgrind rt-tests qemu-system-arm"
  [csharp]="mono-devel nunit-console libnunit-cil-dev pkg-config"
  [ecat]="iproute2"
  [ros2]="python3 python3-venv python3-dev cmake ninja-build g++"
)

missing=()
for group in "$@"; do
  pkgs=${GROUPS_PKGS[$group]:-}
  if [[ -z "$pkgs" ]]; then
    echo "install-deps: unknown group '$group' (known: ${!GROUPS_PKGS[*]})" >&2
    exit 2
  fi
  for p in $pkgs; do
    if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q 'install ok installed'; then
      missing+=("$p")
    fi
  done
done

if [[ ${#missing[@]} -eq 0 ]]; then
  exit 0
fi

echo "install-deps: installing ${missing[*]}"
SUDO=""
if [[ $(id -u) -ne 0 ]]; then
  SUDO="sudo"
fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
