#!/usr/bin/env bash
# Configures and builds moslam, fuzzes the g2o reader, the message decoders, the journal, the
# template and perception cache decoders and the other text file readers for a bounded time each,
# then runs every test
# (ctest's summary is the last thing printed).
#   BUILD_DIR (default build), MOSLAM_FUZZ_SECONDS (default 30; 0 skips the fuzz run).
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD_DIR=${BUILD_DIR:-build}
JOBS=${JOBS:-$(nproc)}

cmake -S . -B "$BUILD_DIR" -G Ninja -DCMAKE_BUILD_TYPE=Release
cmake --build "$BUILD_DIR" -j "$JOBS"

if [[ "${MOSLAM_FUZZ_SECONDS:-30}" != 0 ]]; then
  ./scripts/fuzz.sh "${MOSLAM_FUZZ_SECONDS:-30}"
fi

ctest --test-dir "$BUILD_DIR" --output-on-failure -j "$JOBS"
