#!/usr/bin/env bash
# Installs every build and test dependency of moslam from Debian packages.
# Non-interactive and idempotent: packages already present are left as they are.
set -euo pipefail

PACKAGES=(
  build-essential cmake ninja-build pkg-config git
  libeigen3-dev libsuitesparse-dev
  libopenblas-pthread-dev  # static BLAS/LAPACK of CHOLMOD in the pose-graph executables (cmake/FindCHOLMOD.cmake)
  libcli11-dev nlohmann-json3-dev libspdlog-dev libfmt-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  libceres-dev            # independent cross-check in bench/ only
  clang libclang-rt-14-dev  # libFuzzer target for the g2o reader
  python3-matplotlib jq   # plots and tables of bench/ and scripts/ (README figures)
  cyclonedds-dev cyclonedds-tools libcycloneddsidl0  # robots as processes over DDS
  iproute2 iptables       # scripts/test-network.sh: namespaces, shaped links
  libopencv-dev libpcl-dev  # perception front-end: images, DNN detector, PCL registration
)

source "$(dirname "${BASH_SOURCE[0]}")/lib/debian-packages.sh"
install_debian_packages "${PACKAGES[@]}"
echo "setup: all ${#PACKAGES[@]} dependency packages present"
