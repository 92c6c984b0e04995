#!/usr/bin/env bash
# Configures and builds the solver benchmark (Release, build-bench/) and runs it: moslam
# Gauss-Newton / Levenberg-Marquardt against Ceres on the 3D graphs of ../shared/datasets/pgo.
# Arguments go to moslam_bench_solve, e.g.
#   scripts/bench-solve.sh --repeats 5 --json bench-solve.json
#   scripts/bench-solve.sh -d sphere2500 -d torus3D
# Environment: BUILD_DIR (default build-bench), MOSLAM_DATASETS_DIR (default ../shared/datasets).
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
BUILD_DIR="${BUILD_DIR:-$ROOT/build-bench}"

cmake_args=(-S "$ROOT" -B "$BUILD_DIR" -DCMAKE_BUILD_TYPE=Release -DMOSLAM_BUILD_BENCH=ON
            -DMOSLAM_BUILD_TESTS=OFF)
command -v ninja >/dev/null && [[ ! -f "$BUILD_DIR/CMakeCache.txt" ]] && cmake_args+=(-G Ninja)
[[ -n "${MOSLAM_DATASETS_DIR:-}" ]] && cmake_args+=(-DMOSLAM_DATASETS_DIR="$MOSLAM_DATASETS_DIR")

cmake "${cmake_args[@]}" >/dev/null
cmake --build "$BUILD_DIR" --target moslam_bench_solve
exec "$BUILD_DIR/bench/moslam_bench_solve" "$@"
