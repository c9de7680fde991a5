#!/usr/bin/env bash
# Runs every fuzz harness of tests/fuzz (docs/fuzzing.md) for a share of MINUTES (default 10),
# with libFuzzer, AddressSanitizer and UndefinedBehaviorSanitizer, built with clang in
# ./build-fuzz.
#
#   scripts/fuzz.sh [MINUTES] [HARNESS...]      e.g. scripts/fuzz.sh 30, scripts/fuzz.sh 5 ply stl
#
# Keeps what it finds:
# - inputs that crash, hang or exhaust memory: tests/fuzz/findings/<harness>/ (crash-*, timeout-*,
#   oom-*). Fix the defect, then move the input to tests/fuzz/regressions/<harness>/, which ctest
#   replays in every ordinary build (ctest -L fuzz).
# - inputs that reach new code: build-fuzz/corpus/<harness>/ (outside git; the next run starts
#   from it). The seeds in tests/fuzz/corpus/<harness>/ are read, never written.
# Environment: FUZZ_JOBS (parallel builds, default: nproc), FUZZ_TIMEOUT (s per input, default
# 10, 60 for document), FUZZ_RSS_MB (memory limit per input, default 2048), FUZZ_NO_BUILD=1
# (use build-fuzz as is).
# Exit status: 0 when no harness found anything new, 1 otherwise, 2 on a setup failure.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
minutes="${1:-10}"
shift || true
all=(usb_board usb_host trajectory scene stl obj ply clipboard document calibration_file vtu node_ele
     fk_batch ik_batch tension_batch substructure_cache)
if (($#)); then harnesses=("$@"); else harnesses=("${all[@]}"); fi
if ! [[ "$minutes" =~ ^[0-9]+([.][0-9]+)?$ ]]; then
  echo "fuzz.sh: MINUTES must be a number, got '$minutes'" >&2
  exit 2
fi

# clang 14 with its libFuzzer and sanitizer runtimes (Debian 12 packages).
if ! command -v clang++ >/dev/null 2>&1 || ! compgen -G "/usr/lib/llvm-*/lib/clang/*/lib/linux/libclang_rt.fuzzer-x86_64.a" >/dev/null; then
  sudo_cmd=()
  [ "$(id -u)" -eq 0 ] || sudo_cmd=(sudo)
  echo "fuzz.sh: installing clang and libclang-rt-14-dev"
  "${sudo_cmd[@]}" apt-get update -qq
  DEBIAN_FRONTEND=noninteractive "${sudo_cmd[@]}" apt-get install -y -qq --no-install-recommends \
    clang libclang-rt-14-dev
fi

build="$here/build-fuzz"
if [ "${FUZZ_NO_BUILD:-0}" != 1 ]; then
  launcher=()
  command -v ccache >/dev/null 2>&1 && launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache -DCMAKE_C_COMPILER_LAUNCHER=ccache)
  export CCACHE_BASEDIR="${CCACHE_BASEDIR:-$here}"  # relative paths: objects shared across checkouts
  # ccache hashes the working directory into every -g compile unless told not to, which made
  # a second checkout (a CI clone, a worktree) miss every object; its debug info then names
  # the directory of the checkout that compiled the object first.
  export CCACHE_NOHASHDIR="${CCACHE_NOHASHDIR:-1}"
  CC=clang CXX=clang++ cmake -S "$here" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    -DSPIDARCAD_FUZZ=ON -DSPIDARCAD_SANITIZE=address,undefined -DSPIDARCAD_BUILD_TESTS=OFF \
    -DSPIDARCAD_BUILD_BENCH=OFF "${launcher[@]}" >/dev/null
  targets=()
  for h in "${harnesses[@]}"; do targets+=("${h}_fuzz"); done
  nice cmake --build "$build" -j "${FUZZ_JOBS:-$(nproc)}" --target "${targets[@]}"
fi

seconds=$(awk -v m="$minutes" -v n="${#harnesses[@]}" 'BEGIN { s = int(m * 60 / n); print (s < 1 ? 1 : s) }')
export ASAN_OPTIONS="${ASAN_OPTIONS:-abort_on_error=1:detect_leaks=1:allocator_may_return_null=1}"
export LSAN_OPTIONS="${LSAN_OPTIONS:-suppressions=$here/tests/sanitizers/lsan.supp:print_suppressions=0}"
export UBSAN_OPTIONS="${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}"
summary=()
status=0
for h in "${harnesses[@]}"; do
  exe="$build/tests/fuzz/${h}_fuzz"
  [ -x "$exe" ] || { echo "fuzz.sh: no harness $exe" >&2; exit 2; }
  seeds="$here/tests/fuzz/corpus/$h"
  regressions="$here/tests/fuzz/regressions/$h"
  work="$build/corpus/$h"
  findings="$here/tests/fuzz/findings/$h"
  mkdir -p "$work" "$findings"
  before=$(find "$findings" -type f | wc -l)
  log="$build/logs/$h.log"
  mkdir -p "$(dirname "$log")"
  dirs=("$work" "$seeds")
  [ -d "$regressions" ] && dirs+=("$regressions")
  # Seconds per input, and in all. A document may ask for its meshes on open: the workbench seed
  # takes 0.5 s in the ordinary build and 13 s in this one (ASan, UBSan, coverage), and the six
  # seeds about 45 s, so `document` gets 60 s per input (unless FUZZ_TIMEOUT says otherwise) and
  # 60 s more than its share, which would otherwise end before the first mutation.
  timeout="${FUZZ_TIMEOUT:-10}"
  total="$seconds"
  if [ "$h" = document ]; then
    timeout="${FUZZ_TIMEOUT:-60}"
    total=$((seconds + 60))
  fi
  echo "fuzz.sh: $h for $total s (log $log)"
  # -fork=1 with -ignore_*: a crash is saved and fuzzing goes on until the time is up. An input
  # is reported slow (slow-unit-*, a finding) only past its timeout.
  (cd "$build" && nice "$exe" -fork=1 -ignore_crashes=1 -ignore_timeouts=1 -ignore_ooms=1 \
    -max_total_time="$total" -timeout="$timeout" -report_slow_units="$timeout" \
    -rss_limit_mb="${FUZZ_RSS_MB:-2048}" -artifact_prefix="$findings/" -print_final_stats=1 \
    "${dirs[@]}" >"$log" 2>&1) || true
  after=$(find "$findings" -type f | wc -l)
  # Fork mode prints "exec/s N" per job; the last one is the rate of the last job.
  runs=$(grep -Eo 'exec/s:? [0-9]+' "$log" | tail -1 | awk '{print $2}' || true)
  cov=$(grep -Eo 'cov: [0-9]+' "$log" | tail -1 | awk '{print $2}' || true)
  new=$((after - before))
  ((new > 0)) && status=1
  summary+=("$(printf '%-14s %8s exec/s  cov %6s  corpus %5s  new findings %d' "$h" "${runs:-?}" \
    "${cov:-?}" "$(find "$work" -type f | wc -l)" "$new")")
done
extra=""
[[ " ${harnesses[*]} " == *" document "* ]] && extra=", document 60 s more"
echo "fuzz.sh: summary (${seconds} s per harness$extra; findings in tests/fuzz/findings/)"
printf '  %s\n' "${summary[@]}"
exit "$status"
