#!/usr/bin/env bash
# Installs every Debian package conica needs, then configures and builds into build/
# (executables in build/bin/). Safe to rerun.
#   scripts/setup.sh            # Release build
#   BUILD_DIR=b scripts/setup.sh -DCONICA_SANITIZE=ON   # extra CMake arguments pass through
set -euo pipefail
cd "$(dirname "$0")/.."

PACKAGES=(
  build-essential cmake ninja-build pkg-config git clang-format
  libeigen3-dev libzmq3-dev cppzmq-dev protobuf-compiler libprotobuf-dev
  libspdlog-dev libgtest-dev libgmock-dev libbenchmark-dev libcli11-dev libceres-dev
  calculix-ccx  # conica-lab fem-reference: the continuum reference (docs/validation.md)
  libsuitesparse-dev  # CHOLMOD: the implicit system's sparse factor (server/core/sparse_system.h)
  # single-threaded OpenBLAS for CHOLMOD's supernodal factor (Debian picks it over ATLAS): the
  # phantom's factorisation 7 ms against ATLAS's 16 ms (docs/performance.md, "Multi-rate serving")
  libopenblas0-serial
  tetgen  # scripts/mesh-liver-fine.sh: the finer liver of configs/liver-fine-ef30.pbtxt
  python3-zmq python3-protobuf python3-matplotlib python3-numpy python3-websockets python3-meshio
  python3-venv python3-pip python3-setuptools python3-wheel python3-pytest
  # the one-node Slurm cluster of the library sweep's CI step (scripts/slurm/ci-cluster.sh)
  slurm-wlm munge
  # conica-ros (clients/ros): ROS 1 from Debian, rospy and rosmaster and the message packages
  python3-rospy python3-rosmaster python3-geometry-msgs python3-std-msgs python3-visualization-msgs
)

source scripts/apt-ensure.sh
apt_ensure setup "${PACKAGES[@]}"

BUILD_DIR=${BUILD_DIR:-build}
cmake -S . -B "$BUILD_DIR" -G Ninja -DCMAKE_BUILD_TYPE=${BUILD_TYPE:-Release} "$@" >/dev/null
cmake --build "$BUILD_DIR" -j"$(nproc)"
# The finer liver of configs/liver-fine-ef30.pbtxt (TetGen from liver2.msh's boundary).
scripts/mesh-liver-fine.sh "$BUILD_DIR/meshes/liver-fine.msh"
