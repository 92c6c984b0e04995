#!/usr/bin/env bash
# Which of moslam's own lines and functions the test suite runs: a build instrumented for gcov
# (build-coverage/, -O1 so that the suite stays within minutes), the whole ctest suite, then
# scripts/lib/coverage_summary.py (totals, the files with most lines never run, every function
# never run). Not part of scripts/test.sh.
# Usage: scripts/coverage.sh
set -euo pipefail

repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build="$repo/build-coverage"

cmake -S "$repo" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release \
  -DCMAKE_CXX_FLAGS_RELEASE="-O1 -DNDEBUG" -DCMAKE_CXX_FLAGS="--coverage" \
  -DCMAKE_EXE_LINKER_FLAGS="--coverage" -DCMAKE_SHARED_LINKER_FLAGS="--coverage" >/dev/null
cmake --build "$build" -j "$(nproc)"
find "$build" -name '*.gcda' -delete
(cd "$build" && ctest -j "$(nproc)" --timeout 900 --output-on-failure)
python3 "$repo/scripts/lib/coverage_summary.py" "$build" "$repo"
