#!/usr/bin/env bash
# Solver benchmarks (not tests): configures and builds Release in build-bench/, then
#   scripts/bench-solve.sh [--runs N] [-d DATASET ...] [--json FILE]
#       whole processes (bench/whole_process.py): `moslam solve FILE` beside Ceres on the same
#       initial estimate (bench/ceres_solve.cc), wall time and peak memory, medians of N (5)
#       interleaved runs, `moslam --help`, the load average before and after; the README's table;
#   scripts/bench-solve.sh --crosscheck [--repeats 3 --json FILE ...]
#       in one process per solver (bench/solve_crosscheck.cc): moslam GN / LM and Ceres from the
#       same estimate with tight tolerances, costs and residuals compared (the cross-check).
# Environment: BUILD_DIR (default build-bench), MOSLAM_DATASETS_DIR (default ../shared/datasets).
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
BUILD_DIR="${BUILD_DIR:-$ROOT/build-bench}"
DATASETS="${MOSLAM_DATASETS_DIR:-$ROOT/../shared/datasets}"

cmake_args=(-S "$ROOT" -B "$BUILD_DIR" -DCMAKE_BUILD_TYPE=Release -DMOSLAM_BUILD_BENCH=ON
            -DMOSLAM_BUILD_TESTS=OFF)
command -v ninja >/dev/null && [[ ! -f "$BUILD_DIR/CMakeCache.txt" ]] && cmake_args+=(-G Ninja)
[[ -n "${MOSLAM_DATASETS_DIR:-}" ]] && cmake_args+=(-DMOSLAM_DATASETS_DIR="$MOSLAM_DATASETS_DIR")
cmake "${cmake_args[@]}" >/dev/null

if [[ "${1:-}" == --crosscheck ]]; then
  shift
  cmake --build "$BUILD_DIR" --target moslam_bench_solve
  exec "$BUILD_DIR/bench/moslam_bench_solve" "$@"
fi
cmake --build "$BUILD_DIR" --target moslam ceres_solve process_stats
exec /usr/bin/python3 "$ROOT/bench/whole_process.py" --moslam "$BUILD_DIR/apps/moslam" \
  --ceres "$BUILD_DIR/bench/ceres_solve" --stats "$BUILD_DIR/bench/process_stats" \
  --datasets "$DATASETS/pgo" "$@"
