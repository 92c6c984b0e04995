#!/usr/bin/env bash
# Robust distributed solve on spoiled blocks_world folders (issue: wrong inter-robot loop
# closures). For every team size and outlier fraction P: `moslam spoil` adds wrong separators
# (seeded), `moslam dgs --robust` solves them (separator check, then GNC-TLS by the robots), and
# the estimate is compared with the clean folder's centralized optimum (`moslam solve --out`,
# same gauge: no alignment). blocks_world's information is the identity while its factors fit to
# r^T Omega r <= 0.3 at the optimum, so the GNC threshold is 1 (--gnc-threshold).
# Environment: BUILD_DIR / MOSLAM (scripts/lib/moslam.sh), SEED (default 1), ROBOTS, FRACTIONS.
# Writes docs/robust_g2o.json and prints the Markdown table.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/lib/moslam.sh"
SEED="${SEED:-1}"
ROBOTS="${ROBOTS:-4 9 16 25 36 49}"
FRACTIONS="${FRACTIONS:-0.1 0.3 0.5 0.7 0.9}"
DATA="$ROOT/../shared/datasets/distributed-mapper/CogRob_distributed-mapper/distributed_mapper_core/data/blocks_world"
WORK="$(mktemp -d)"
trap 'rm -rf "$WORK"' EXIT
mkdir -p "$ROOT/docs"

rows=()
for r in $ROBOTS; do
  clean="$DATA/${r}robots"
  "$MOSLAM" solve "$clean" --json --out "$WORK/clean_$r/" > "$WORK/clean_$r.json"
  for p in $FRACTIONS; do
    spoiled="$WORK/spoiled_${r}_$p"
    "$MOSLAM" spoil "$clean" --fraction "$p" --seed "$SEED" --out "$spoiled" > /dev/null
    "$MOSLAM" dgs "$spoiled" --robust --gnc-threshold 1 --separator-test measurement --json --out "$WORK/est_${r}_$p" \
      | tail -n 1 > "$WORK/dgs_${r}_$p.json"
    rows+=("$(python3 "$ROOT/scripts/lib/robust_g2o_row.py" "$r" "$p" "$WORK/clean_$r.json" \
      "$WORK/clean_$r" "$spoiled/outliers.txt" "$WORK/dgs_${r}_$p.json" "$WORK/est_${r}_$p")")
  done
done
printf '%s\n' "${rows[@]}" | jq -s '.' > "$ROOT/docs/robust_g2o.json"
echo "Command: \`scripts/robust-g2o.sh\` (seed $SEED)"
echo
python3 - "$ROOT/docs/robust_g2o.json" <<'PY'
import json, sys
print("| robots | P | separators (wrong) | rejected by the check | rejected in all | wrong kept / right rejected | GNC rounds | kept cost / clean optimum - 1 | ATE* vs clean (m) | bytes: all / weights + checks |")
print("|---:|---:|---|---:|---:|---|---:|---:|---:|---|")
for r in json.load(open(sys.argv[1])):
    print(f"| {r['robots']} | {r['fraction']} | {r['separators']} ({r['wrong']}) | {r['check_rejected']} | "
          f"{r['rejected']} | {r['wrong_kept']} / {r['right_rejected']} | {r['rounds']} | "
          f"{r['cost_rel']:.1e} | {r['ate']:.1e} | {r['bytes'] / 1e6:.2f} MB / {r['extra_bytes'] / 1e3:.1f} kB |")
PY
