#!/usr/bin/env bash
# Paper Table 3: per-robot memory and communication, object map against point cloud, by the
# paper's formulas (K = 640 x 480 points per frame, C = 32 bytes per point, P = 10000 points per
# object model, L = 32 bytes per object) and by our measured serialized bytes; 6 robots, paper
# noise, 10 runs. Writes docs/table3.json.
# Environment: BUILD_DIR (default build-release; configured Release if it has no CMakeCache.txt),
# MOSLAM (a built moslam binary: skips the build), RUNS (default 10), SEED (default 1). Extra arguments go to every `moslam simulate` call.
set -euo pipefail

source "$(dirname "${BASH_SOURCE[0]}")/lib/simulate-table.sh"


for scenario in chairs25 house; do
  run "Table 3, $scenario" --scenario "$scenario" --robots 6 --table memory "$@"
done
finish "$ROOT/docs/table3.json"
