#!/usr/bin/env bash
# Benchmark of the distributed solver to the centralized optimum (not a test): builds `moslam`
# (Release, its own build dir) and runs `moslam dgs --refine --json` (Gauss-Seidel order) with
# eta = 1e-1 and 1e-2 over
#   blocks_world 2, 4, 9, 16, 25, 36, 49 robots (the distributed-mapper folders), and
#   sphere2500, torus3D, cubicle (--drop-indefinite-coupling) split into 2, 4, 16, 64 robots,
# twice per row, in the same run:
#   paper      --stages one-level --refine-preconditioner sweeps: the paper's one-level DGS, then
#              the refinement preconditioned by the sweeps alone (moslam's pipeline before the
#              two-level refinement);
#   two-level  the default of `moslam dgs --refine`: two-level DGS, then the refinement
#              preconditioned by the sweeps around a coarse correction.
# The JSON lines (tagged "pipeline") go to $BUILD_DIR/dgs_bench.jsonl; bench/dgs_table.py prints
# the Markdown tables (also written to $BUILD_DIR/dgs_table.md) and draws docs/dgs_scaling.png.
#   scripts/bench-dgs.sh                 # everything (~30 min on 2 cores)
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
echo "load average at the start: $(cut -d' ' -f1-3 /proc/loadavg)" >&2
run() {  # run DATASET ROBOTS ETA INPUT [ARGS...]
  local dataset="$1" robots="$2" eta="$3" input="$4" pipeline flags
  shift 4
  for pipeline in paper two-level; do
    if [[ "$pipeline" == paper ]]; then
      flags=(--stages one-level --refine-preconditioner sweeps)
    else
      flags=()
    fi
    echo "moslam dgs $input $* ${flags[*]} --eta-rot $eta --eta-pose $eta --refine --json" >&2
    "$MOSLAM" dgs "$input" "$@" "${flags[@]}" --eta-rot "$eta" --eta-pose "$eta" --order gs \
        --refine --json \
      | tail -n 1 \
      | "$PYTHON" -c 'import json, sys; j = json.loads(sys.stdin.read()); j["dataset"] = sys.argv[1]; j["requested_robots"] = int(sys.argv[2]); j["pipeline"] = sys.argv[3]; print(json.dumps(j))' \
          "$dataset" "$robots" "$pipeline" >> "$OUT.partial"
  done
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
echo "load average at the end: $(cut -d' ' -f1-3 /proc/loadavg)" >&2

"$PYTHON" "$ROOT/bench/dgs_table.py" "$OUT" --plot "$ROOT/docs/dgs_scaling.png" \
  | tee "$BUILD_DIR/dgs_table.md"
