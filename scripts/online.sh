#!/usr/bin/env bash
# Online mapping (issue 13): the robots in range solve their joint graph at every rendezvous
# (two-level DGS, error-bound rule, refinement; Jacobi order as the robot processes), chairs25
# and house, 6 robots, 10 runs. Prints the table, writes docs/online.json and the plots of the
# team's map error after each rendezvous, docs/online_chairs25.svg and docs/online_house.svg.
# Environment: BUILD_DIR (default build-release), MOSLAM (a built binary: skips the build),
# RUNS (default 10), SEED (default 1). Extra arguments go to every `moslam simulate` call.
set -euo pipefail

source "$(dirname "${BASH_SOURCE[0]}")/lib/simulate-table.sh"

for scenario in chairs25 house; do
  run "Online mapping, $scenario" --online --scenario "$scenario" --robots 6 \
    --plot "$ROOT/docs/online_$scenario.svg" "$@"
done
finish "$ROOT/docs/online.json"
