#!/usr/bin/env bash
# Installs every Debian package conica needs, then configures and builds into build/
# (executables in build/bin/). Safe to rerun.
#   scripts/setup.sh            # Release build
#   BUILD_DIR=b scripts/setup.sh -DCONICA_SANITIZE=ON   # extra CMake arguments pass through
set -euo pipefail
cd "$(dirname "$0")/.."

PACKAGES=(
  build-essential cmake ninja-build pkg-config git
  libeigen3-dev libzmq3-dev cppzmq-dev protobuf-compiler libprotobuf-dev
  libspdlog-dev libgtest-dev libgmock-dev libbenchmark-dev libcli11-dev libceres-dev
  python3-zmq python3-protobuf python3-matplotlib python3-numpy python3-websockets
)

missing=()
for p in "${PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if ((${#missing[@]})); then
  SUDO=""
  [[ $(id -u) -ne 0 ]] && SUDO="sudo"
  echo "setup: installing ${missing[*]}"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq "${missing[@]}" >/dev/null
fi

BUILD_DIR=${BUILD_DIR:-build}
cmake -S . -B "$BUILD_DIR" -G Ninja -DCMAKE_BUILD_TYPE=${BUILD_TYPE:-Release} "$@" >/dev/null
cmake --build "$BUILD_DIR" -j"$(nproc)"
