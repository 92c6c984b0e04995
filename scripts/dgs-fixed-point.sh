#!/usr/bin/env bash
# How close DGS gets to its fixed point (the centralized two-stage estimate) at eta = 1e-6 on every
# blocks_world folder, Gauss-Seidel and Jacobi, with the paper's stopping rule (change <= eta) and
# with the error-bound rule (change * rho / (1 - rho) <= eta; dgs_types.h). Prints a Markdown
# table (README, "DGS at eta = 1e-6"); the JSON lines go to $BUILD_DIR/dgs_fixed_point.jsonl.
#   scripts/dgs-fixed-point.sh            (~6 min on 2 cores)
# Environment: BUILD_DIR (default build-bench-dgs), MOSLAM (a built binary: skips the build),
# MOSLAM_DATASETS_DIR (default ../shared/datasets), ETA (default 1e-6).
set -euo pipefail

BUILD_DIR="${BUILD_DIR:-$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)/build-bench-dgs}"
source "$(dirname "${BASH_SOURCE[0]}")/lib/moslam.sh"
DATASETS="${MOSLAM_DATASETS_DIR:-$ROOT/../shared/datasets}"
BLOCKS="$DATASETS/distributed-mapper/CogRob_distributed-mapper/distributed_mapper_core/data/blocks_world"
ETA="${ETA:-1e-6}"
mkdir -p "$BUILD_DIR"
OUT="$BUILD_DIR/dgs_fixed_point.jsonl"
: >"$OUT"

echo "| robots | order | stop | sweeps (rot + pose) | ATE* to fixed point (m) | ARE* (deg) | time (s) |"
echo "|---|---|---|---|---|---|---|"
for n in 2 4 9 16 25 36 49; do
  for order in gs jacobi; do
    for stop in change error-bound; do
      line=$("$MOSLAM" dgs "$BLOCKS/${n}robots" --eta-rot "$ETA" --eta-pose "$ETA" --order "$order" \
               --stop "$stop" --max-iter 200000 --json | tail -n 1)
      echo "$line" >>"$OUT"
      jq -r '[.robots, .order, .stopping, .iterations_rotation, .iterations_pose,
              .fixed_point_ate_poses, .fixed_point_are_poses_deg, .seconds] | @tsv' <<<"$line" |
        awk -F'\t' '{printf "| %d | %s | %s | %d + %d | %.2e | %.2e | %.2f |\n", $1, $2, $3, $4, $5, $6, $7, $8}'
    done
  done
done
