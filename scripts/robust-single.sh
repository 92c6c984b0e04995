#!/usr/bin/env bash
# Robust solve of single-robot pose graphs with wrong loop closures. For every dataset, outlier
# fraction P and GNC threshold: `moslam spoil` adds wrong loop closures between poses that are not
# consecutive (seeded; in the plane for 2D files), `moslam solve --robust` solves them with GNC-TLS
# alone (--separator-support 0) and with the loop closures first checked pairwise through the
# odometry (robust/loop_consistency.h), `moslam dgs --robots R --robust` splits the file into R
# robots that solve it (each checks its own loop closures through its odometry, the separator
# check those between two), and each estimate is compared with the clean file's optimum
# (`moslam solve --out`, the same gauge: no alignment).
# Environment: BUILD_DIR / MOSLAM (scripts/lib/moslam.sh), SEED (default 1), DATASETS (files of
# ../shared/datasets/pgo without .g2o), FRACTIONS, THRESHOLDS (0: GNC's default, 22.46), ROBOTS
# (default 4; empty: no dgs), DGS_ARGS (more flags for `moslam dgs`, e.g. "--refine-linear-tol
# 1e-3"), JSON (default docs/robust_single.json). Writes JSON and prints the Markdown table.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/lib/moslam.sh"
SEED="${SEED:-1}"
DATASETS="${DATASETS:-input_INTEL_g2o CSAIL}"
FRACTIONS="${FRACTIONS:-0.1 0.3 0.5 0.7}"
THRESHOLDS="${THRESHOLDS:-0 5}"
ROBOTS="${ROBOTS-4}"
read -r -a DGS_EXTRA <<< "${DGS_ARGS:-}"
JSON="${JSON:-$ROOT/docs/robust_single.json}"
DATA="$ROOT/../shared/datasets/pgo"
WORK="$(mktemp -d)"
trap 'rm -rf "$WORK"' EXIT
mkdir -p "$ROOT/docs"

rows=()
for d in $DATASETS; do
  "$MOSLAM" solve "$DATA/$d.g2o" --json --out "$WORK/clean_$d.g2o" > /dev/null
  for p in $FRACTIONS; do
    spoiled="$WORK/spoiled_${d}_$p"
    "$MOSLAM" spoil "$DATA/$d.g2o" --fraction "$p" --seed "$SEED" --out "$spoiled" > /dev/null
    for c in $THRESHOLDS; do
      run="$WORK/${d}_${p}_$c"
      "$MOSLAM" solve "$spoiled" --robust --gnc-threshold "$c" --separator-support 0 --json \
        --out "$run.alone/" | tail -n 1 > "$run.alone.json"
      "$MOSLAM" solve "$spoiled" --robust --gnc-threshold "$c" --json --out "$run.checked/" \
        | tail -n 1 > "$run.checked.json"
      dgs=()
      for r in $ROBOTS; do
        "$MOSLAM" dgs "$spoiled/0.g2o" --robots "$r" --robust --gnc-threshold "$c" --json \
          "${DGS_EXTRA[@]}" --out "$run.dgs$r" | tail -n 1 > "$run.dgs$r.json"
        dgs+=("$r" "$run.dgs$r.json" "$run.dgs$r")
      done
      rows+=("$(python3 "$ROOT/scripts/lib/robust_single_row.py" "$d" "$p" "$c" \
        "$spoiled/outliers.txt" "$WORK/clean_$d.g2o" "$run.alone.json" "$run.alone" \
        "$run.checked.json" "$run.checked" "${dgs[@]}")")
    done
  done
done
printf '%s\n' "${rows[@]}" | jq -s '.' > "$JSON"
echo "Command: \`scripts/robust-single.sh\` (seed $SEED)"
echo
python3 - "$JSON" <<'PY'
import json, sys
rows = json.load(open(sys.argv[1]))
robots = list(rows[0]["dgs"]) if rows else []
head = ["dataset", "P", "GNC threshold", "loop closures (wrong)",
        "GNC alone: wrong kept / right rejected", "largest position error (m)",
        "with the check: wrong kept / right rejected", "largest position error (m)"]
for n in robots:
    head += [f"dgs, {n} robots: wrong kept / right rejected", "largest position error (m)"]
print("| " + " | ".join(head) + " |")
print("|---|---:|---:|---|" + "---|---:|" * (2 + len(robots)))
cell = lambda j: f"{j['wrong_kept']} / {j['right_rejected']} | {j['max_position_difference']:.2g}"
for r in rows:
    t = r["gnc_threshold"] or 22.46
    cells = [cell(r["gnc_alone"]), cell(r["checked"])] + [cell(r["dgs"][n]) for n in robots]
    print(f"| {r['dataset']} | {r['fraction']} | {t:g} | {r['loop_closures']} ({r['wrong']}) | "
          + " | ".join(cells) + " |")
PY
