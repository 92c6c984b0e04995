#!/usr/bin/env bash
# Paper Table 1: accuracy for 2, 4 and 6 robots (noise 5 deg / 0.2 m, the paper's default),
# 10 Monte Carlo runs, chairs25 and house; plus association precision/recall. Writes docs/table1.json
# and the Fig. 4 style plots docs/fig4_chairs25.svg and docs/fig4_house.svg (6 robots).
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


for scenario in chairs25 house; do
  run "Table 1, $scenario" --scenario "$scenario" --robots 2 4 6 --table accuracy association "$@"
  "$MOSLAM" simulate --scenario "$scenario" --robots 6 --runs 1 --seed "$SEED" --table accuracy \
    --plot "$ROOT/docs/fig4_$scenario.svg" "$@" >/dev/null
done
finish "$ROOT/docs/table1.json"
