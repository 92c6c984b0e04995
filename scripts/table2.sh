#!/usr/bin/env bash
# Paper Table 2: accuracy for noise (1 deg, 0.1 m), (5, 0.1), (10, 0.2), (15, 0.3) with 6 robots on
# chairs25, 10 Monte Carlo runs, with the factor information of the simulated noise (--information
# noise) and with the fixed information of 5 deg / 0.2 m (--information fixed, the paper's trend:
# cost grows with noise^2). Writes docs/table2.json.
# Environment: BUILD_DIR (default build-release; configured Release if it has no CMakeCache.txt),
# MOSLAM (a built moslam binary: skips the build), RUNS (default 10), SEED (default 1). Extra arguments go to every `moslam simulate` call.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
BUILD_DIR="${BUILD_DIR:-$ROOT/build-release}"
RUNS="${RUNS:-10}"
SEED="${SEED:-1}"
if [[ -z "${MOSLAM:-}" ]]; then
  if [[ ! -f "$BUILD_DIR/CMakeCache.txt" ]]; then
    cmake_args=(-S "$ROOT" -B "$BUILD_DIR" -DCMAKE_BUILD_TYPE=Release -DMOSLAM_BUILD_BENCH=OFF)
    command -v ninja >/dev/null && cmake_args+=(-G Ninja)
    cmake "${cmake_args[@]}" >/dev/null
  fi
  cmake --build "$BUILD_DIR" --target moslam >/dev/null
  MOSLAM="$BUILD_DIR/apps/moslam"
fi
mkdir -p "$ROOT/docs"

# run NAME ARGS...: prints the Markdown of `moslam simulate ARGS --json`, keeps its JSON line.
declare -a JSON_PARTS=()
run() {
  local name="$1"; shift
  local out
  out="$("$MOSLAM" simulate --runs "$RUNS" --seed "$SEED" "$@" --json)"
  echo "### $name"
  echo
  echo "Command: \`moslam simulate --runs $RUNS --seed $SEED $*\`"
  echo
  echo "$out" | sed '$d'
  echo
  JSON_PARTS+=("$(echo "$out" | tail -n 1 | jq -c --arg name "$name" '{name: $name} + .')")
}
# finish FILE: writes the collected JSON objects as one array.
finish() {
  printf '%s\n' "${JSON_PARTS[@]}" | jq -s '.' > "$1"
  echo "JSON: ${1#$ROOT/}"
}


for information in noise fixed; do
  run "Table 2, chairs25, information $information" --scenario chairs25 --robots 6 \
    --sigma-rot 1 5 10 15 --sigma-trans 0.1 0.1 0.2 0.3 --information "$information" \
    --table accuracy "$@"
done
finish "$ROOT/docs/table2.json"
