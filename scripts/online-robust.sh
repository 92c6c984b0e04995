#!/usr/bin/env bash
# Online mapping with wrong associations (README, "Online mapping ... with wrong pairs"): the
# robots in range solve at every rendezvous, least squares or robust (`--robust`: the separator
# check and GNC-TLS of RunRobustDgs on each group, the pairs among its robots robust, the ones it
# rejects set aside), with a fraction P of wrong pairs injected at every rendezvous. One table
# per scenario, a row per (P, solve). Environment: as scripts/online.sh (RUNS default 10, SEED
# default 1), SCENARIOS (default "chairs25 house"), FRACTIONS (default "0 0.3 0.7 0.9"), ROBOTS
# (default 6), JSON (default docs/online_robust.json). Extra arguments go to every `moslam
# simulate` call (e.g. --initial-poses unknown).
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/lib/simulate-table.sh"
SCENARIOS="${SCENARIOS:-chairs25 house}"
FRACTIONS="${FRACTIONS:-0 0.3 0.7 0.9}"
ROBOTS="${ROBOTS:-6}"
JSON="${JSON:-$ROOT/docs/online_robust.json}"

for scenario in $SCENARIOS; do
  echo "### $scenario, $ROBOTS robots"
  echo
  echo "Commands: \`moslam simulate --online --runs $RUNS --seed $SEED --scenario $scenario --robots $ROBOTS --outliers P [--robust] $*\`"
  echo
  header=1
  for p in $FRACTIONS; do
    for robust in "" "--robust"; do
      out="$("$MOSLAM" simulate --online --runs "$RUNS" --seed "$SEED" --scenario "$scenario" \
        --robots "$ROBOTS" --outliers "$p" $robust "$@" --json)"
      table="$(echo "$out" | sed '$d')"
      if [[ $header == 1 ]]; then echo "$table" | head -n 2; header=0; fi
      echo "$table" | tail -n +3
      # Without the per-solve points (docs/online.json has them for the least-squares runs).
      JSON_PARTS+=("$(echo "$out" | tail -n 1 | jq -c --arg s "$scenario" --arg p "$p" \
        --arg r "${robust:-ls}" '{scenario: $s, outliers: $p, solve: $r} + . |
        del(.rows[].runs[].points)')")
    done
  done
  echo
done
finish "$JSON"
