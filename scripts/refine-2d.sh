#!/usr/bin/env bash
# The distributed solver (`moslam dgs --refine`, the default two-level pipeline) on the 2D
# benchmark graphs of ../shared/datasets/pgo, each split into 2, 4 and 16 contiguous blocks, with
# the refinement's default linear tolerance (conjugate gradients to 1e-2) and with 1e-3. Prints a
# Markdown table (README, "The 2D benchmark graphs"); the JSON lines go to
# $BUILD_DIR/refine_2d.jsonl.
#   scripts/refine-2d.sh            (~65 min on 2 cores, 50 of them ais2klinik's)
# Environment: BUILD_DIR (default build-bench-dgs), MOSLAM (a built binary: skips the build),
# MOSLAM_DATASETS_DIR (default ../shared/datasets), FILES, ROBOTS, TOLERANCES (space-separated),
# PIECE_POSES (--refine-coarse-piece-poses, default 0: one rigid motion per robot; the JSON lines
# then go to $BUILD_DIR/refine_2d_pieces.jsonl).
set -euo pipefail

BUILD_DIR="${BUILD_DIR:-$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)/build-bench-dgs}"
source "$(dirname "${BASH_SOURCE[0]}")/lib/moslam.sh"
DATASETS="${MOSLAM_DATASETS_DIR:-$ROOT/../shared/datasets}"
FILES="${FILES:-CSAIL MIT input_INTEL_g2o intel input_M3500_g2o manhattan kitti_00 kitti_02 kitti_05 kitti_06 kitti_07 kitti_08 kitti_09 ais2klinik city10000}"
ROBOTS="${ROBOTS:-2 4 16}"
TOLERANCES="${TOLERANCES:-1e-2 1e-3}"
mkdir -p "$BUILD_DIR"
PIECE_POSES="${PIECE_POSES:-0}"
OUT="$BUILD_DIR/refine_2d.jsonl"
[ "$PIECE_POSES" = 0 ] || OUT="$BUILD_DIR/refine_2d_pieces.jsonl"
: >"$OUT"

echo "load average at the start: $(cut -d' ' -f1-3 /proc/loadavg)" >&2
echo "| file | robots | CG tolerance | GN cost | two-stage / GN - 1 | refined / GN - 1 | GN steps (rejected; halvings) | steps at the sweep cap | sweeps | bytes | seconds |"
echo "|---|---:|---:|---:|---:|---:|---|---:|---:|---:|---:|"
for f in $FILES; do
  for n in $ROBOTS; do
    for tol in $TOLERANCES; do
      line=$("$MOSLAM" dgs "$DATASETS/pgo/$f.g2o" --robots "$n" --refine \
               --refine-linear-tol "$tol" --refine-coarse-piece-poses "$PIECE_POSES" --json |
             tail -n 1)
      echo "$line" >>"$OUT"
      jq -r --arg f "$f" --arg tol "$tol" '
        [$f, .robots, $tol, .centralized_cost, (.two_stage_cost / .centralized_cost - 1),
         (.final_cost / .centralized_cost - 1), .refine_steps, .refine_rejected_steps,
         .refine_backtracks,
         (if .termination_refine == "max iterations" then ": step limit" else "" end),
         ([.refine_history[] | select(.linear_converged | not)] | length),
         .iterations_refine, (.bytes / 1e6), .seconds] | @tsv' <<<"$line" |
        awk -F'\t' '{printf "| %s | %d | %s | %.6g | %.2g | %.2g | %d (%d; %d)%s | %d | %d | %.1f MB | %.1f |\n",
                     $1, $2, $3, $4, $5, $6, $7, $8, $9, $10, $11, $12, $13, $14}'
    done
  done
done
echo "load average at the end: $(cut -d' ' -f1-3 /proc/loadavg)" >&2
