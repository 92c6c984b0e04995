#!/usr/bin/env bash
# The perception front-end measured (README "Perception front-end"): not a test.
#   1. renders held-out TUM RGB-D sequences (chairs25 and house, seed 101: worlds and trajectories
#      the detector never saw) and runs `moslam perceive --world` on them with each consensus
#      (CONSENSUS, default "prerejective sac-ia"): detections, acceptance, pose errors against
#      ground truth, milliseconds per detection (median and 90th percentile) and per stage;
#   2. per class, the same over the four sequences (first consensus);
#   3. template start-up: the house templates built into an empty cache, then read from it;
#   4. runs `moslam simulate --perception rendered` on chairs25 with 2 robots, every frame
#      perceived (the robots close loops: the default with rendered perception), with the
#      sampled-measurement runs of the same seed beside it, without loop closure (the paper's
#      rule, sampled measurements' default) and with it (SIMULATE=0 skips).
# Times are wall clock per detection on one thread (the two threads of `perceive` register two
# detections at once); the machine's load is printed before and after.
# Writes $BUILD_DIR/perception/*.json and prints Markdown.
#   scripts/bench-perception.sh          (~10 min on 2 cores with SAC-IA, ~3 min without)
# Environment: BUILD_DIR (default build-release), MOSLAM (a built binary: skips the build),
# POSES (default 40: poses per robot), EVERY (default 2: perceive every 2nd pose),
# CONSENSUS (default "prerejective sac-ia"), SIMULATE (default 1), DETECTOR_FLAGS (default none:
# the detector's operating point for `perceive`, e.g. "--per-class-nms --nms 0.45").
set -euo pipefail

POSES="${POSES:-40}"
EVERY="${EVERY:-2}"
CONSENSUS="${CONSENSUS:-prerejective sac-ia}"
SIMULATE="${SIMULATE:-1}"
read -r -a DETECTOR_FLAGS <<<"${DETECTOR_FLAGS:-}"
source "$(dirname "${BASH_SOURCE[0]}")/lib/moslam.sh"
OUT="$BUILD_DIR/perception"
rm -rf "$OUT"
mkdir -p "$OUT"
CACHE="$OUT/template-cache"

echo "Machine: $(nproc) cores; load before: $(cut -d' ' -f1-3 /proc/loadavg)"
echo
for scenario in chairs25 house; do
  "$MOSLAM" render --scenario "$scenario" --robots 2 --poses "$POSES" --seed 101 --format tum \
    --out "$OUT/$scenario" >/dev/null
done

# Median and 90th percentile (linear interpolation) of a JSON array on stdin, in jq.
JQ_STATS='def q(p): sort as $s | ($s|length) as $n | if $n == 0 then null else
  (p * ($n - 1)) as $at | ($at|floor) as $lo | ([$lo + 1, $n - 1]|min) as $hi |
  $s[$lo] + ($at - $lo) * ($s[$hi] - $s[$lo]) end;
def r0: if . == null then "-" else (. | round | tostring) end;'

echo "### Held-out rendered sequences (seed 101, one frame in ${EVERY})"
echo
echo "| sequence | consensus | detections | accepted | median pose error | ms per detection: median / p90 | stage medians (ms): prepare / consensus / gate / GICP |"
echo "|---|---|---|---|---|---|---|"
for consensus in $CONSENSUS; do
  for scenario in chairs25 house; do
    for robot in 0 1; do
      base="$OUT/${scenario}_robot${robot}_${consensus}"
      "$MOSLAM" perceive "$OUT/$scenario/robot$robot" --world "$OUT/$scenario/world.json" \
        --every "$EVERY" --consensus "$consensus" --template-cache "$CACHE" "${DETECTOR_FLAGS[@]}" \
        --out "$base.json" --json 2>/dev/null | tail -n 1 >"$base.summary.json"
      jq -r --arg s "$scenario robot $robot" --arg c "$consensus" "$JQ_STATS"'
        .classes.all as $a |
        "| \($s) | \($c) | \(.detections) | \(.accepted) | \((.median_translation_error // 0) * 1000 | round) mm / \((.median_rotation_error_deg // 0) * 100 | round / 100) deg | \($a.register_ms.median | r0) / \($a.register_ms.p90 | r0) | \($a.stage_ms_median.prepare | r0) / \($a.stage_ms_median.consensus | r0) / \($a.stage_ms_median.gate | r0) / \($a.stage_ms_median.gicp | r0) |"' \
        "$base.summary.json"
    done
  done
done
echo

first="${CONSENSUS%% *}"
echo "### Per class, the four sequences together ($first; last row: every detection)"
echo
echo "| class | detections | registered | accepted | ms per detection: median / p90 | median pose error |"
echo "|---|---|---|---|---|---|"
jq -rs "$JQ_STATS"'
  [.[].frames[].objects[]] | (group_by(.label)[], map(.label = "all classes")) |
  { label: .[0].label, n: length,
    registered: [.[] | select(.register_ms != null)] | length,
    accepted: [.[] | select(.status == "accepted")] | length,
    ms: [.[] | .register_ms // empty],
    t: [.[] | select(.status == "accepted") | .ground_truth.translation_error // empty],
    r: [.[] | select(.status == "accepted") | .ground_truth.rotation_error_deg // empty] } |
  "| \(.label) | \(.n) | \(.registered) | \(.accepted) | \(.ms | q(0.5) | r0) / \(.ms | q(0.9) | r0) | \(if (.t|length) > 0 then "\(.t | q(0.5) * 1000 | round) mm / \(.r | q(0.5) * 100 | round / 100) deg" else "-" end) |"' \
  "$OUT"/*_"$first".json
echo

echo "### Template start-up (house robot 0: every class it sees)"
echo
rm -rf "$OUT/startup-cache"
for run in "empty cache" "cached"; do
  "$MOSLAM" perceive "$OUT/house/robot0" --world "$OUT/house/world.json" --every "$EVERY" \
    --template-cache "$OUT/startup-cache" --json 2>/dev/null | tail -n 1 |
    jq -r --arg r "$run" '"- \($r): \(.template_seconds * 100 | round / 100) s for the templates (\(.templates_from_cache) read from the cache)"'
done
echo
echo "Load after the perception runs: $(cut -d' ' -f1-3 /proc/loadavg)"

if [[ "$SIMULATE" == "1" ]]; then
  echo
  echo "### moslam simulate --scenario chairs25 --robots 2 --poses $POSES: rendered vs sampled"
  echo
  /usr/bin/time -f "(rendered run: %e s wall, %M KB peak)" \
    "$MOSLAM" simulate --scenario chairs25 --robots 2 --runs 1 --seed 1 --poses "$POSES" \
    --perception rendered --perceive-every 1 --template-cache "$CACHE" \
    --table perception accuracy association --json 2>&1 | tee "$OUT/simulate_rendered.txt" |
    grep -v '^{'
  echo
  "$MOSLAM" simulate --scenario chairs25 --robots 2 --runs 1 --seed 1 --poses "$POSES" \
    --table accuracy association --json | tee "$OUT/simulate_sampled.txt" | sed '$d'
  echo
  echo "Sampled, with the robots' loop closure too (--loop-closure):"
  echo
  "$MOSLAM" simulate --scenario chairs25 --robots 2 --runs 1 --seed 1 --poses "$POSES" \
    --table accuracy association --loop-closure --json |
    tee "$OUT/simulate_sampled_loop_closure.txt" | sed '$d'
fi
