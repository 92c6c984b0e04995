#!/usr/bin/env bash
# One-level (the paper's) against two-level DGS (`moslam dgs --coarse`), side by side in one run:
# sweeps (rotation + pose), distance to the centralized two-stage estimate (the fixed point both
# converge to), cost ratio to centralized GN and bytes, for eta = 1e-1 and 1e-2 (both stages,
# Gauss-Seidel order, no refinement) over
#   blocks_world 2, 4, 9, 16, 25, 36, 49 robots (the distributed-mapper folders), and
#   sphere2500 and torus3D split into 4, 16, 64 robots.
# Prints a Markdown table (about 3 min on 2 cores). Not a test: a benchmark.
# Environment: BUILD_DIR (default build-release), MOSLAM (a built moslam binary: skips the
# build), MOSLAM_DATASETS_DIR (default ../shared/datasets).
set -euo pipefail

source "$(dirname "${BASH_SOURCE[0]}")/lib/moslam.sh"
DATASETS="${MOSLAM_DATASETS_DIR:-$ROOT/../shared/datasets}"
BLOCKS="$DATASETS/distributed-mapper/CogRob_distributed-mapper/distributed_mapper_core/data/blocks_world"

# row DATASET ROBOTS ETA INPUT [ARGS...]: one table row, both variants.
row() {
  local dataset="$1" robots="$2" eta="$3" input="$4"
  shift 4
  local one two
  one="$("$MOSLAM" dgs "$input" "$@" --eta-rot "$eta" --eta-pose "$eta" --json | tail -n 1)"
  two="$("$MOSLAM" dgs "$input" "$@" --eta-rot "$eta" --eta-pose "$eta" --coarse --json | tail -n 1)"
  python3 - "$dataset" "$robots" "$eta" "$one" "$two" <<'PY'
import json, sys
d, n, eta = sys.argv[1:4]
a, b = (json.loads(x) for x in sys.argv[4:6])
sweeps = lambda j: f"{j['iterations_rotation']} + {j['iterations_pose']}"
print(f"| {d} | {n} | {eta} | {sweeps(a)} | {sweeps(b)} | {a['fixed_point_ate_poses']:.1e} | "
      f"{b['fixed_point_ate_poses']:.1e} | {a['two_stage_cost_ratio']:.4f} | "
      f"{b['two_stage_cost_ratio']:.4f} | {a['bytes'] / 1e3:.1f} | {b['bytes'] / 1e3:.1f} |")
PY
}

echo "| dataset | robots | eta | one-level sweeps (rot + pose) | two-level sweeps | one-level ATE* to fixed point (m) | two-level ATE* to fixed point (m) | one-level cost / GN | two-level cost / GN | one-level kB | two-level kB |"
echo "|---|---:|---:|---|---|---:|---:|---:|---:|---:|---:|"
for eta in 1e-1 1e-2; do
  for n in 2 4 9 16 25 36 49; do row blocks_world "$n" "$eta" "$BLOCKS/${n}robots"; done
  for name in sphere2500 torus3D; do
    for n in 4 16 64; do row "$name" "$n" "$eta" "$DATASETS/pgo/$name.g2o" --robots "$n"; done
  done
done
