#!/usr/bin/env bash
# The whole test suite under the sanitizers, where any report fails the test that made it (the
# executables the tests start, `moslam`, `moslam-robot` and `moslam-perception`, are instrumented
# alike). The fuzz targets (scripts/fuzz.sh) check the decoders this way; this checks everything
# else the tests run. Not part of scripts/test.sh (each build takes 12-16 min on 2 cores).
#   SANITIZER=address (default): AddressSanitizer and UndefinedBehaviorSanitizer, build-asan/
#     (-O1 -g, assertions on: Eigen's size and index checks too); the suite about 5x slower.
#   SANITIZER=thread: ThreadSanitizer, build-tsan/ (-O1 -g): data races and lock-order
#     inversions among the threads moslam starts (the transports' receivers, the DGS nodes and
#     team drivers of the tests, perception's workers). Cyclone DDS, PCL and OpenCV come
#     uninstrumented from Debian: TSan sees their locks and memcpy (intercepted), not their own
#     loads and stores;
#     scripts/tsan-suppressions.txt lists the reports of theirs it hides, and why.
# Usage: [SANITIZER=address|thread] scripts/sanitize.sh [ctest arguments, e.g. -R Robust]
set -euo pipefail

repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
case "${SANITIZER:-address}" in
  address)
    build="$repo/build-asan"
    # Eigen frees with its own aligned free under AddressSanitizer unless told that malloc aligns
    # (as it does unsanitized): PCL and OpenCV, prebuilt from Debian, allocate clouds with malloc,
    # so the same belief on both sides of the library boundary.
    san="-fsanitize=address,undefined -fno-omit-frame-pointer -fno-sanitize-recover=undefined"
    san="$san -DEIGEN_MALLOC_ALREADY_ALIGNED=1"
    export ASAN_OPTIONS="${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=0:halt_on_error=1}"
    export UBSAN_OPTIONS="${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}"
    ;;
  thread)
    build="$repo/build-tsan"
    san="-fsanitize=thread -fno-omit-frame-pointer"
    # A report makes the process exit with 66, so its test fails; history_size keeps the stack of
    # the earlier access of a race in long tests; the suppressions are for code not moslam's.
    tsan="halt_on_error=1:exitcode=66:second_deadlock_stack=1:history_size=4"
    # OpenBLAS's pool (CHOLMOD's BLAS) hands work to its threads through spin flags TSan cannot
    # see: every hand-over would read as a race. One thread, as moslam's commands already run it
    # (apps/cli.cc, TuneProcessForSolving).
    export OPENBLAS_NUM_THREADS=1
    export TSAN_OPTIONS="${TSAN_OPTIONS:-$tsan:suppressions=$repo/scripts/tsan-suppressions.txt}"
    ;;
  *)
    echo "sanitize.sh: SANITIZER must be address or thread, not '${SANITIZER}'" >&2
    exit 2
    ;;
esac

cmake -S "$repo" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g $san" -DCMAKE_C_FLAGS_RELWITHDEBINFO="-O1 -g $san" \
  -DCMAKE_EXE_LINKER_FLAGS="$san" -DCMAKE_SHARED_LINKER_FLAGS="$san" \
  -DMOSLAM_BUILD_BENCH=OFF >/dev/null
cmake --build "$build" -j "$(nproc)"
(cd "$build" && ctest -j "$(nproc)" --timeout 1800 --output-on-failure "$@")
