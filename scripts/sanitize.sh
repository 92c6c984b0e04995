#!/usr/bin/env bash
# The whole test suite under AddressSanitizer and UndefinedBehaviorSanitizer: a build of every
# target with both (build-asan/, -O1 -g, assertions on: Eigen's size and index checks too), then
# ctest, where any sanitizer report fails the test that made it (the executables the tests start,
# `moslam`, `moslam-robot` and `moslam-perception`, are instrumented alike). The fuzz targets
# (scripts/fuzz.sh) check the decoders this way; this checks everything else the tests run.
# Not part of scripts/test.sh (about 30 min to build on 2 cores, the suite 2-3x slower).
# Usage: scripts/sanitize.sh [ctest arguments, e.g. -R Robust]
set -euo pipefail

repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build="$repo/build-asan"
# Eigen frees with its own aligned free under AddressSanitizer unless told that malloc aligns (as
# it does unsanitized): PCL and OpenCV, prebuilt from Debian, allocate clouds with malloc, so the
# same belief on both sides of the library boundary.
san="-fsanitize=address,undefined -fno-omit-frame-pointer -fno-sanitize-recover=undefined"
san="$san -DEIGEN_MALLOC_ALREADY_ALIGNED=1"

cmake -S "$repo" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g $san" -DCMAKE_C_FLAGS_RELWITHDEBINFO="-O1 -g $san" \
  -DCMAKE_EXE_LINKER_FLAGS="$san" -DCMAKE_SHARED_LINKER_FLAGS="$san" \
  -DMOSLAM_BUILD_BENCH=OFF >/dev/null
cmake --build "$build" -j "$(nproc)"
export ASAN_OPTIONS="${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=0:halt_on_error=1}"
export UBSAN_OPTIONS="${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}"
(cd "$build" && ctest -j "$(nproc)" --timeout 1800 --output-on-failure "$@")
