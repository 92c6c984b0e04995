#!/usr/bin/env bash
# Benchmark of the distributed Gauss-Seidel solver (not a test): builds `moslam` (Release, its own
# build dir) and runs `moslam dgs --json --refine` (Gauss-Seidel order) with eta = 1e-1 and 1e-2
# (both stages) over
#   blocks_world 2, 4, 9, 16, 25, 36, 49 robots (the distributed-mapper folders), and
#   sphere2500, torus3D, cubicle (--drop-indefinite-coupling) split into 2, 4, 16, 64 robots.
# The JSON lines go to $BUILD_DIR/dgs_bench.jsonl; bench/dgs_table.py prints the Markdown table
# (also written to $BUILD_DIR/dgs_table.md) and draws docs/dgs_scaling.png.
#   scripts/bench-dgs.sh                 # everything (~40 min on 2 cores; cubicle/64 ~8 min per eta)
#   scripts/bench-dgs.sh sphere2500      # only the datasets named (blocks_world, sphere2500, ...)
# Environment: BUILD_DIR (default build-bench-dgs), MOSLAM_DATASETS_DIR (default
# ../shared/datasets), MOSLAM (a built moslam binary: skips the build), PYTHON (default
# /usr/bin/python3, which has matplotlib from python3-matplotlib).
set -euo pipefail

BUILD_DIR="${BUILD_DIR:-$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)/build-bench-dgs}"
source "$(dirname "${BASH_SOURCE[0]}")/lib/moslam.sh"
DATASETS="${MOSLAM_DATASETS_DIR:-$ROOT/../shared/datasets}"
PYTHON="${PYTHON:-/usr/bin/python3}"
BLOCKS="$DATASETS/distributed-mapper/CogRob_distributed-mapper/distributed_mapper_core/data/blocks_world"
mkdir -p "$BUILD_DIR"

selected() {  # selected NAME: whether the dataset was asked for (all when no arguments)
  [[ ${#WANTED[@]} -eq 0 ]] && return 0
  local w
  for w in "${WANTED[@]}"; do [[ "$w" == "$1" ]] && return 0; done
  return 1
}
WANTED=("$@")

OUT="$BUILD_DIR/dgs_bench.jsonl"
: > "$OUT.partial"
run() {  # run DATASET ROBOTS ETA INPUT [ARGS...]
  local dataset="$1" robots="$2" eta="$3" input="$4"
  shift 4
  echo "moslam dgs $input $* --eta-rot $eta --eta-pose $eta --refine --json" >&2
  "$MOSLAM" dgs "$input" "$@" --eta-rot "$eta" --eta-pose "$eta" --order gs --refine --json \
    | tail -n 1 \
    | "$PYTHON" -c 'import json, sys; j = json.loads(sys.stdin.read()); j["dataset"] = sys.argv[1]; j["requested_robots"] = int(sys.argv[2]); print(json.dumps(j))' \
        "$dataset" "$robots" >> "$OUT.partial"
}

for eta in 1e-1 1e-2; do
  if selected blocks_world; then
    for n in 2 4 9 16 25 36 49; do run blocks_world "$n" "$eta" "$BLOCKS/${n}robots"; done
  fi
  for name in sphere2500 torus3D cubicle; do
    selected "$name" || continue
    extra=()
    [[ "$name" == cubicle ]] && extra=(--drop-indefinite-coupling)
    for n in 2 4 16 64; do
      run "$name" "$n" "$eta" "$DATASETS/pgo/$name.g2o" --robots "$n" "${extra[@]}"
    done
  done
done
mv "$OUT.partial" "$OUT"

"$PYTHON" "$ROOT/bench/dgs_table.py" "$OUT" --plot "$ROOT/docs/dgs_scaling.png" \
  | tee "$BUILD_DIR/dgs_table.md"
