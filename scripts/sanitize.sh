#!/usr/bin/env bash
# Sanitizer pass (docs/fuzzing.md): builds everything with AddressSanitizer and
# UndefinedBehaviorSanitizer in ./build-asan (GCC, -DSPIDARCAD_SANITIZE=address,undefined), runs
# the whole ctest suite there (window tests under Xvfb; the fuzz replays included), then a short
# libFuzzer pass of every harness (scripts/fuzz.sh, clang, ./build-fuzz).
#
#   scripts/sanitize.sh [FUZZ_MINUTES] [CTEST_ARGS...]
#
# FUZZ_MINUTES (default 6, shared by the 12 harnesses; 0 skips the fuzz pass). Further arguments
# go to ctest (e.g. -L fuzz, -R haptics). Prints the time of each stage. Exit status: non-zero
# when the build, a test or the fuzz pass failed.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
fuzz_minutes="${1:-6}"
shift || true
# The Debian packages come from scripts/setup.sh (run it once on a new machine).
command -v cmake >/dev/null 2>&1 || { echo "sanitize.sh: run scripts/setup.sh first" >&2; exit 2; }
build="$here/build-asan"
jobs="$(nproc)"
launcher=()
command -v ccache >/dev/null 2>&1 && launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache -DCMAKE_C_COMPILER_LAUNCHER=ccache)

start=$(date +%s)
cmake -S "$here" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DSPIDARCAD_SANITIZE=address,undefined -DSPIDARCAD_BUILD_BENCH=OFF "${launcher[@]}" >/dev/null
nice cmake --build "$build" -j "$jobs"
built=$(date +%s)
echo "sanitize.sh: build $((built - start)) s"

# Leaks are errors too, except in the libraries listed in tests/fuzz/lsan.supp (not ours).
export ASAN_OPTIONS="${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=1:strict_string_checks=1:detect_stack_use_after_return=1}"
export LSAN_OPTIONS="${LSAN_OPTIONS:-suppressions=$here/tests/fuzz/lsan.supp:print_suppressions=0}"
export UBSAN_OPTIONS="${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}"
status=0
cd "$build"
if command -v xvfb-run >/dev/null 2>&1; then
  xvfb-run -a -s "-screen 0 1280x1024x24" ctest --output-on-failure -j "$jobs" "$@" || status=1
else
  ctest --output-on-failure -j "$jobs" "$@" || status=1
fi
tested=$(date +%s)
echo "sanitize.sh: tests $((tested - built)) s"

if [ "$fuzz_minutes" != 0 ]; then
  unset ASAN_OPTIONS LSAN_OPTIONS UBSAN_OPTIONS
  "$here/scripts/fuzz.sh" "$fuzz_minutes" || status=1
  echo "sanitize.sh: fuzz pass $(($(date +%s) - tested)) s"
fi
echo "sanitize.sh: total $(($(date +%s) - start)) s, status $status"
exit "$status"
