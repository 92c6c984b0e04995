#!/usr/bin/env bash
# Past the paper's scale: generated worlds with 16, 64 and 128 robots (ROBOTS to change), 1 run
# each (RUNS): iterations, cost ratio against centralized, bytes, wall time. Writes
# docs/scale.json.
# Environment: BUILD_DIR (default build-release; configured Release if it has no CMakeCache.txt),
# MOSLAM (a built moslam binary: skips the build), RUNS (default 10), SEED (default 1). Extra arguments go to every `moslam simulate` call.
set -euo pipefail

source "$(dirname "${BASH_SOURCE[0]}")/lib/simulate-table.sh"


RUNS="${RUNS_SCALE:-1}"
for robots in ${ROBOTS:-16 64 128}; do
  run "Scale, generated, $robots robots" --scenario generated --robots "$robots" --table scale "$@"
done
finish "$ROOT/docs/scale.json"
