#!/usr/bin/env bash
# The perception front-end measured (issue 5; README "Perception front-end"): not a test.
#   1. renders held-out TUM RGB-D sequences (chairs25 and house, seed 101: worlds and trajectories
#      the detector never saw) and runs `moslam perceive --world` on them: detections, the
#      12-inlier gate's rejections, pose errors against ground truth, milliseconds per stage;
#   2. runs `moslam simulate --perception rendered` on chairs25 with 2 robots, every frame
#      perceived (one in 2 left robot 1 without a shared object at 40 and 60 poses): the whole
#      system on rendered frames, with the sampled-measurement run of the same seed beside it.
# Writes $BUILD_DIR/perception/*.json and prints Markdown.
#   scripts/bench-perception.sh          (~15-25 min on 2 cores)
# Environment: BUILD_DIR (default build-release), MOSLAM (a built binary: skips the build),
# POSES (default 40: poses per robot), EVERY (default 2: perceive every 2nd pose).
set -euo pipefail

POSES="${POSES:-40}"
EVERY="${EVERY:-2}"
source "$(dirname "${BASH_SOURCE[0]}")/lib/moslam.sh"
OUT="$BUILD_DIR/perception"
rm -rf "$OUT"
mkdir -p "$OUT"

echo "### Perception on held-out rendered sequences (seed 101, one frame in ${EVERY})"
echo
echo "| sequence | frames | detections | accepted | rejected by the 12-inlier gate | median pose error | ms/frame detect / segment / register |"
echo "|---|---|---|---|---|---|---|"
for scenario in chairs25 house; do
  "$MOSLAM" render --scenario "$scenario" --robots 2 --poses "$POSES" --seed 101 --format tum \
    --out "$OUT/$scenario" >/dev/null
  for robot in 0 1; do
    line=$("$MOSLAM" perceive "$OUT/$scenario/robot$robot" --world "$OUT/$scenario/world.json" \
             --every "$EVERY" --out "$OUT/${scenario}_robot${robot}.json" --json 2>/dev/null | tail -n 1)
    echo "$line" >"$OUT/${scenario}_robot${robot}_summary.json"
    jq -r --arg s "$scenario robot $robot" '"| \($s) | \(.frames) | \(.detections) | \(.accepted) | \(.rejected_by_inlier_gate) | \((.median_translation_error // 0) * 1000 | round) mm / \((.median_rotation_error_deg // 0) * 100 | round / 100) deg | \(.ms_per_frame.detect | floor) / \(.ms_per_frame.segment | floor) / \(.ms_per_frame.register | floor) |"' <<<"$line"
  done
done
echo
echo "### moslam simulate --scenario chairs25 --robots 2 --poses $POSES: rendered vs sampled"
echo
"$MOSLAM" simulate --scenario chairs25 --robots 2 --runs 1 --seed 1 --poses "$POSES" \
  --perception rendered --perceive-every 1 --table perception accuracy association \
  --json | tee "$OUT/simulate_rendered.txt" | sed '$d'
echo
"$MOSLAM" simulate --scenario chairs25 --robots 2 --runs 1 --seed 1 --poses "$POSES" \
  --table accuracy association --json | tee "$OUT/simulate_sampled.txt" | sed '$d'
