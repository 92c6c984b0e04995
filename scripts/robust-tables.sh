#!/usr/bin/env bash
# Robust multi-robot object SLAM (README, "Robustness"): one table per scenario.
#   1. Unknown initial poses beside known ones, no injected outliers: rendezvous alignment
#      (aligned / refused / wrong), association precision and recall, ground-truth errors; the
#      robust solve on, which must change nothing (robust = LS).
#   2. Wrong associations injected at every rendezvous, P in 0 .. 0.9 (known initial poses):
#      outlier precision / recall of the robust solve, ground-truth ATE / ARE of the least-squares
#      DGS, the robust DGS and the outlier-free solve, and the robust estimate against the
#      outlier-free one on its worst run.
# generated: runs in which a robot never links to robot 0 are left out and counted
# (--skip-unlinked). Environment: as scripts/table1.sh (RUNS default 10, SEED default 1),
# SCENARIOS (default "chairs25 house generated"), FRACTIONS (default "0 0.1 0.3 0.5 0.7 0.9"),
# ROBOTS (default "2 4 6"), POSES (default "known unknown"; empty: no table 1), JSON (default
# docs/robust_tables.json). Extra arguments go to every `moslam simulate` call (e.g.
# --perception rendered --perception-cache DIR: each run perceived once, replayed in the other rows).
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/lib/simulate-table.sh"
SCENARIOS="${SCENARIOS:-chairs25 house generated}"
FRACTIONS="${FRACTIONS:-0 0.1 0.3 0.5 0.7 0.9}"
ROBOTS="${ROBOTS:-2 4 6}"
POSES="${POSES-known unknown}"
JSON="${JSON:-$ROOT/docs/robust_tables.json}"
read -ra robots <<< "$ROBOTS"

for scenario in $SCENARIOS; do
  for poses in $POSES; do
    run "Initial poses $poses, $scenario" --scenario "$scenario" --robots "${robots[@]}" \
      --initial-poses "$poses" --robust --skip-unlinked --table robust "$@"
  done
  for p in $FRACTIONS; do
    run "Outliers P = $p, $scenario" --scenario "$scenario" --robots "${robots[@]}" --outliers "$p" \
      --robust --skip-unlinked --table robust "$@"
  done
done
finish "$JSON"
