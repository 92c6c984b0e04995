# Sourced by scripts/table1.sh, table2.sh, table3.sh and scale.sh: finds or builds the moslam
# binary and provides run (one `moslam simulate` table, Markdown printed, JSON kept) and finish.
# Environment: BUILD_DIR (default build-release), MOSLAM (a built binary: skips the build),
# RUNS (default 10), SEED (default 1).
source "$(dirname "${BASH_SOURCE[0]}")/moslam.sh"
RUNS="${RUNS:-10}"
SEED="${SEED:-1}"
mkdir -p "$ROOT/docs"

# run NAME ARGS...: prints the Markdown of `moslam simulate ARGS --json`, keeps its JSON line.
declare -a JSON_PARTS=()
run() {
  local name="$1"; shift
  local out
  out="$("$MOSLAM" simulate --runs "$RUNS" --seed "$SEED" "$@" --json)"
  echo "### $name"
  echo
  echo "Command: \`moslam simulate --runs $RUNS --seed $SEED $*\`"
  echo
  echo "$out" | sed '$d'
  echo
  JSON_PARTS+=("$(echo "$out" | tail -n 1 | jq -c --arg name "$name" '{name: $name} + .')")
}
# finish FILE: writes the collected JSON objects as one array.
finish() {
  printf '%s\n' "${JSON_PARTS[@]}" | jq -s '.' > "$1"
  echo "JSON: ${1#$ROOT/}"
}

