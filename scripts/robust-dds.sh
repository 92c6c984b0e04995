#!/usr/bin/env bash
# The robust solve over DDS (issue: wrong inter-robot loop closures, robots as processes): README's
# table of `moslam team ... --robust`. Each row runs the robots as processes on loopback (`moslam
# team`, which also runs the in-process robust solve of the same options and compares the two);
# the spoiled blocks_world rows also run `moslam dgs` with the same options, in-process, for the
# list of separators it rejects (`team` reports counts, `spoil` lists the wrong ones).
# Environment: BUILD_DIR (default build-release) or MOSLAM (a built moslam, with moslam-robot
# beside it: skips the build), SEED (default 1, of `moslam spoil`).
# Writes docs/robust_dds.json and prints the Markdown table.
set -euo pipefail
MOSLAM_ALSO=moslam-robot
source "$(dirname "${BASH_SOURCE[0]}")/lib/moslam.sh"
SEED="${SEED:-1}"
DATA="$ROOT/../shared/datasets/distributed-mapper/CogRob_distributed-mapper/distributed_mapper_core/data/blocks_world"
WORK="$(mktemp -d)"
trap 'rm -rf "$WORK"' EXIT
mkdir -p "$ROOT/docs"
echo "load before: $(cut -d' ' -f1-3 /proc/loadavg)" >&2

SPOILED_OPTIONS=(--coarse --refine --stop error-bound --gnc-threshold 1 --separator-test measurement)
rows=()
i=0
for r in 4 9; do
  for p in 0.3 0.7; do
    spoiled="$WORK/spoiled_${r}_$p"
    "$MOSLAM" spoil "$DATA/${r}robots" --fraction "$p" --seed "$SEED" --out "$spoiled" >/dev/null
    "$MOSLAM" team --data "$spoiled" "${SPOILED_OPTIONS[@]}" --robust --json --out "$WORK/team_$i" \
      | tail -n 1 >"$WORK/team_$i.json"
    "$MOSLAM" dgs "$spoiled" "${SPOILED_OPTIONS[@]}" --robust --json --out "$WORK/dgs_$i" \
      | tail -n 1 >"$WORK/dgs_$i.json"
    rows+=("$(jq -c --arg name "$r robots, P $p" --rawfile wrong "$spoiled/outliers.txt" \
      --slurpfile dgs "$WORK/dgs_$i.json" '. + {"label": $name,
        wrong: ($wrong | split("\n") | map(select(length > 0) | split(" ") | sort)),
        dgs_outliers: $dgs[0].outliers,
        dgs_rejected: ($dgs[0].rejected | map(sort))} | del(.per_robot)' "$WORK/team_$i.json")")
    i=$((i + 1))
  done
done
for scenario in chairs25 house; do
  "$MOSLAM" team --scenario "$scenario" --robots 6 --robust --json --out "$WORK/team_$i" \
    | tail -n 1 >"$WORK/team_$i.json"
  rows+=("$(jq -c --arg name "$scenario, 6 robots" '. + {"label": $name} | del(.per_robot)' \
    "$WORK/team_$i.json")")
  i=$((i + 1))
done
echo "load after: $(cut -d' ' -f1-3 /proc/loadavg)" >&2
printf '%s\n' "${rows[@]}" | jq -s '.' >"$ROOT/docs/robust_dds.json"

echo "Command: \`scripts/robust-dds.sh\` (seed $SEED)"
echo
python3 - "$ROOT/docs/robust_dds.json" <<'PY'
import json, sys


def kb(b):
    return "0" if b == 0 else f"{b / 1e3:.1f}" if b >= 100 else f"{b / 1e3:.2f}"


def size(b):
    return f"{b / 1e6:.2f} MB" if b >= 1e6 else f"{b / 1e3:.0f} kB"


print("| run | check: left out (in-process) | check bytes: binary / covariance DDS payload | "
      "GNC rounds (in-process) | re-tests (in-process): back | rejected in all | difference | "
      "weight messages: DDS / in-process | weight bytes: DDS payload / in-process | DDS payload | "
      "seconds |")
print("|---|---|---|---|---|---|---|---|---|---|---|")
for r in json.load(open(sys.argv[1])):
    if not r["ok"]:
        sys.exit(f"robust-dds: the team failed on {r['label']}")
    rejected = str(r["in_process_outliers"])
    if "wrong" in r:
        # `dgs` in-process with the same options names the separators; its count must be the team's.
        if r["dgs_outliers"] != r["in_process_outliers"]:
            sys.exit(f"robust-dds: dgs rejected {r['dgs_outliers']}, team's in-process "
                     f"{r['in_process_outliers']} on {r['label']}")
        wrong = {tuple(w) for w in r["wrong"]}
        rejected += f" ({sum(1 for x in r['dgs_rejected'] if tuple(x) in wrong)} wrong)"
    back = r["retest_readmitted"] + r["group_readmitted"]
    print(f"| {r['label']} | {r['check_rejected']} ({r['in_process_check_rejected']}) | "
          f"{kb(r['check_binary_bytes'])} / {kb(r['dds_covariance_bytes'])} kB | "
          f"{r['gnc_rounds']} ({r['in_process_gnc_rounds']}) | "
          f"{r['retests']} ({r['in_process_retests']}): {back} | {rejected} | "
          f"{r['max_difference']:.1e} | {r['weight_messages']} / {r['in_process_weight_messages']} | "
          f"{kb(r['dds_weight_bytes'])} / {kb(r['in_process_weight_bytes'])} kB | "
          f"{size(r['dds_payload_bytes'])} | {r['seconds']:.2f} |")
PY
