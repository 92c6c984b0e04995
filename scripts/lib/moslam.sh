# Sourced by the benchmark and table scripts: sets ROOT (the checkout) and MOSLAM (a built moslam
# binary). When MOSLAM is not set, configures BUILD_DIR (Release, no benchmarks; default
# build-release, or whatever the caller set) once and builds the moslam target there, with the
# executables moslam runs that the caller names in MOSLAM_ALSO (e.g. "moslam-robot").
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
BUILD_DIR="${BUILD_DIR:-$ROOT/build-release}"
if [[ -z "${MOSLAM:-}" ]]; then
  if [[ ! -f "$BUILD_DIR/CMakeCache.txt" ]]; then
    cmake_args=(-S "$ROOT" -B "$BUILD_DIR" -DCMAKE_BUILD_TYPE=Release -DMOSLAM_BUILD_BENCH=OFF)
    command -v ninja >/dev/null && cmake_args+=(-G Ninja)
    cmake "${cmake_args[@]}" >/dev/null
  fi
  # shellcheck disable=SC2086  # MOSLAM_ALSO: a list of target names
  cmake --build "$BUILD_DIR" --target moslam ${MOSLAM_ALSO:-} >/dev/null
  MOSLAM="$BUILD_DIR/apps/moslam"
fi
