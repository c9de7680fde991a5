#!/usr/bin/env bash
# Sanitizer pass (docs/sanitizers.md): builds the test executables and the fuzz corpus replays
# with AddressSanitizer (LeakSanitizer included) and UndefinedBehaviorSanitizer in ./build-asan
# (GCC, -DSPIDARCAD_SANITIZE=address,undefined, -O1 -g1), one target at a time, then runs their
# tests through ctest (window tests under Xvfb) with every sanitizer report fatal.
#
#   scripts/sanitize.sh [--targets LIST] [--jobs N] [--no-build] [--fuzz-minutes M] [-- CTEST_ARGS...]
#
#   --targets LIST    comma-separated build targets whose tests run (default
#                     haptics_tests,fem_tests,modeling_tests,fuzz,app_tests). `fuzz` stands for
#                     every <harness>_fuzz_replay; `all` for every test executable and replay.
#   --jobs N          parallel compile and test jobs (default 2); compiles run under nice -n 19.
#   --no-build        run what build-asan already holds.
#   --fuzz-minutes M  afterwards, a libFuzzer pass of M minutes over every harness (scripts/fuzz.sh,
#                     clang, its own ./build-fuzz); default 0 (none).
#   CTEST_ARGS        passed to ctest, e.g. -R 'Fk\.' or -L hard or -E Window.
#
# Prints the wall time and load average of every build and of the test run (timings also in
# build-asan/sanitize-times.txt). Exit status: 0 when everything built and passed, 1 when a build
# or a test failed (a sanitizer report fails its test), 2 on a usage error.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build="$here/build-asan"
targets_arg="haptics_tests,fem_tests,modeling_tests,fuzz,app_tests"
jobs=2
no_build=0
fuzz_minutes=0
ctest_args=()
usage() { sed -n '2,21p' "${BASH_SOURCE[0]}" | sed 's/^# \{0,1\}//'; }
while (($#)); do
  case "$1" in
    --targets) targets_arg="${2:?--targets needs a list, e.g. haptics_tests,fuzz}"; shift 2 ;;
    --targets=*) targets_arg="${1#*=}"; shift ;;
    --jobs) jobs="${2:?--jobs needs a number}"; shift 2 ;;
    --jobs=*) jobs="${1#*=}"; shift ;;
    --no-build) no_build=1; shift ;;
    --fuzz-minutes) fuzz_minutes="${2:?--fuzz-minutes needs a number}"; shift 2 ;;
    --fuzz-minutes=*) fuzz_minutes="${1#*=}"; shift ;;
    -h | --help) usage; exit 0 ;;
    --) shift; ctest_args=("$@"); break ;;
    *) echo "sanitize.sh: unknown argument '$1' (see scripts/sanitize.sh --help)" >&2; exit 2 ;;
  esac
done
if ! [[ "$jobs" =~ ^[1-9][0-9]*$ ]]; then
  echo "sanitize.sh: --jobs must be a positive integer, got '$jobs'" >&2
  exit 2
fi
if ! [[ "$fuzz_minutes" =~ ^[0-9]+([.][0-9]+)?$ ]]; then
  echo "sanitize.sh: --fuzz-minutes must be a number, got '$fuzz_minutes'" >&2
  exit 2
fi
# The Debian packages come from scripts/setup.sh (run it once on a new machine).
command -v cmake >/dev/null 2>&1 || { echo "sanitize.sh: run scripts/setup.sh first" >&2; exit 2; }
command -v jq >/dev/null 2>&1 || { echo "sanitize.sh: needs jq (apt-get install jq)" >&2; exit 2; }

mkdir -p "$build"
times_file="$build/sanitize-times.txt"
load() { cut -d' ' -f1-3 /proc/loadavg; }
# CPU seconds (user + system, compilers and tests included) of the last timed step: unlike wall
# time they hardly depend on what else the machine runs.
cpu_file="$build/.sanitize-cpu"
timer=()
[ -x /usr/bin/time ] && timer=(/usr/bin/time -q -f "%U %S" -o "$cpu_file")
cpu() { [ -s "$cpu_file" ] && awk '{ printf ", %.0f s CPU", $1 + $2 }' "$cpu_file" && rm -f "$cpu_file"; true; }
note() {
  echo "sanitize.sh: $*"
  echo "$(date -u +%FT%TZ) $*" >>"$times_file"
}

# -O1 and line tables only (-g1): the sanitizer build shares nothing with the ordinary compiler
# cache, and -O1 -g1 compiles in about half the time of RelWithDebInfo's -O2 -g while stack traces
# keep their file:line. NDEBUG as in the ordinary build, so the same code paths run.
launcher=()
command -v ccache >/dev/null 2>&1 && launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache -DCMAKE_C_COMPILER_LAUNCHER=ccache)
export CCACHE_BASEDIR="${CCACHE_BASEDIR:-$here}"  # relative paths: objects shared across checkouts
# ccache hashes the working directory into every -g compile unless told not to, which made
# a second checkout (a CI clone, a worktree) miss every object; its debug info then names
# the directory of the checkout that compiled the object first.
export CCACHE_NOHASHDIR="${CCACHE_NOHASHDIR:-1}"
if [ "$no_build" = 0 ] || [ ! -f "$build/build.ninja" ]; then
  cmake -S "$here" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g1 -DNDEBUG" -DCMAKE_C_FLAGS_RELWITHDEBINFO="-O1 -g1 -DNDEBUG" \
    -DSPIDARCAD_SANITIZE=address,undefined -DSPIDARCAD_BUILD_BENCH=OFF "${launcher[@]}" >/dev/null
fi

# Expand the target list against what the build defines.
mapfile -t known < <(cmake --build "$build" -- -t targets all 2>/dev/null |
  sed -n 's/^\([A-Za-z0-9_]*\(_tests\|_fuzz_replay\)\): .*/\1/p' | grep -v '^cmake_' | sort -u)
targets=()
IFS=',' read -r -a requested <<<"$targets_arg"
for t in "${requested[@]}"; do
  case "$t" in
    "") ;;
    all) targets+=("${known[@]}") ;;
    fuzz) for k in "${known[@]}"; do [[ "$k" == *_fuzz_replay ]] && targets+=("$k"); done ;;
    *)
      if printf '%s\n' "${known[@]}" | grep -qx -- "$t"; then
        targets+=("$t")
      else
        echo "sanitize.sh: unknown target '$t'; known: fuzz, all, ${known[*]}" >&2
        exit 2
      fi ;;
  esac
done
((${#targets[@]})) || { echo "sanitize.sh: --targets selected nothing" >&2; exit 2; }
mapfile -t targets < <(printf '%s\n' "${targets[@]}" | awk '!seen[$0]++')

status=0
start=$(date +%s)
if [ "$no_build" = 0 ]; then
  for t in "${targets[@]}"; do
    t0=$(date +%s)
    l0=$(load)
    if "${timer[@]}" nice -n 19 cmake --build "$build" -j "$jobs" --target "$t"; then
      note "build $t $(($(date +%s) - t0)) s wall$(cpu) (load average $l0 -> $(load))"
    else
      note "build $t FAILED after $(($(date +%s) - t0)) s"
      status=1
    fi
  done
fi

# Every sanitizer report is fatal and prints its stack. Leaks are errors too, except inside the
# libraries listed in tests/sanitizers/lsan.supp (not ours; each entry says why). A failed
# allocation beyond ASan's limit throws std::bad_alloc as it would without the sanitizer.
supp="$here/tests/sanitizers"
export ASAN_OPTIONS="${ASAN_OPTIONS:-halt_on_error=1:abort_on_error=1:detect_leaks=1:strict_string_checks=1:detect_stack_use_after_return=1:check_initialization_order=1:strict_init_order=1:allocator_may_return_null=1}"
export LSAN_OPTIONS="${LSAN_OPTIONS:-suppressions=$supp/lsan.supp:print_suppressions=0}"
export UBSAN_OPTIONS="${UBSAN_OPTIONS:-halt_on_error=1:abort_on_error=1:print_stacktrace=1:suppressions=$supp/ubsan.supp}"

# Run only the tests of the built targets: pick them by the executable of their command. ctest
# numbers the tests -I selects after its other filters (-R, -E, -L), so list them with the same.
cd "$build"
selection="$build/sanitize-tests.txt"
want=$(printf '%s\n' "${targets[@]}" | jq -R . | jq -s .)
indices=$(ctest --show-only=json-v1 "${ctest_args[@]}" | jq -r --argjson want "$want" '
  [.tests | to_entries[] | select((.value.command // [])[0] // "" | split("/") | last |
   IN($want[])) | .key + 1] | map(tostring) | join(",")')
if [ -z "$indices" ]; then
  note "no tests found for ${targets[*]}"
  exit 1
fi
echo "0,0,0,$indices" >"$selection"
runner=()
command -v xvfb-run >/dev/null 2>&1 && runner=(xvfb-run -a -s "-screen 0 1280x1024x24 -noreset")  # run-tests.sh says why
t0=$(date +%s)
l0=$(load)
"${timer[@]}" "${runner[@]}" ctest --output-on-failure -j "$jobs" -I "$selection" "${ctest_args[@]}" ||
  status=1
note "tests of ${targets[*]}: $(($(date +%s) - t0)) s wall$(cpu) with -j $jobs (load average $l0 -> $(load))"

if [ "$fuzz_minutes" != 0 ]; then
  unset ASAN_OPTIONS LSAN_OPTIONS UBSAN_OPTIONS
  t0=$(date +%s)
  "$here/scripts/fuzz.sh" "$fuzz_minutes" || status=1
  note "fuzz pass $(($(date +%s) - t0)) s"
fi
note "total $(($(date +%s) - start)) s, status $status"
exit "$status"
