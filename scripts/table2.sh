#!/usr/bin/env bash
# Paper Table 2: accuracy for noise (1 deg, 0.1 m), (5, 0.1), (10, 0.2), (15, 0.3) with 6 robots on
# chairs25, 10 Monte Carlo runs, with the factor information of the simulated noise (--information
# noise) and with the fixed information of 5 deg / 0.2 m (--information fixed, the paper's trend:
# cost grows with noise^2). Writes docs/table2.json.
# Environment: BUILD_DIR (default build-release; configured Release if it has no CMakeCache.txt),
# MOSLAM (a built moslam binary: skips the build), RUNS (default 10), SEED (default 1). Extra arguments go to every `moslam simulate` call.
set -euo pipefail

source "$(dirname "${BASH_SOURCE[0]}")/lib/simulate-table.sh"


for information in noise fixed; do
  run "Table 2, chairs25, information $information" --scenario chairs25 --robots 6 \
    --sigma-rot 1 5 10 15 --sigma-trans 0.1 0.1 0.2 0.3 --information "$information" \
    --table accuracy "$@"
done
finish "$ROOT/docs/table2.json"
