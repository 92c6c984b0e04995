#!/usr/bin/env bash
# Paper Table 1: accuracy for 2, 4 and 6 robots (noise 5 deg / 0.2 m, the paper's default),
# 10 Monte Carlo runs, chairs25 and house; plus association precision/recall. Writes docs/table1.json
# and the Fig. 4 style plots docs/fig4_chairs25.svg and docs/fig4_house.svg (6 robots).
# Environment: BUILD_DIR (default build-release; configured Release if it has no CMakeCache.txt),
# MOSLAM (a built moslam binary: skips the build), RUNS (default 10), SEED (default 1). Extra arguments go to every `moslam simulate` call.
set -euo pipefail

source "$(dirname "${BASH_SOURCE[0]}")/lib/simulate-table.sh"


for scenario in chairs25 house; do
  run "Table 1, $scenario" --scenario "$scenario" --robots 2 4 6 --table accuracy association "$@"
  "$MOSLAM" simulate --scenario "$scenario" --robots 6 --runs 1 --seed "$SEED" --table accuracy \
    --plot "$ROOT/docs/fig4_$scenario.svg" "$@" >/dev/null
done
finish "$ROOT/docs/table1.json"
