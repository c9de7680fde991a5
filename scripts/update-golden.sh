#!/usr/bin/env bash
# Regenerates the golden results of the headless regression runs (tests/golden/*.csv) from the
# current build: runs the Regression tests of app_tests with SPIDARCAD_UPDATE_GOLDEN=1, which
# then write the goldens in the source tree instead of comparing. Check the new runs' physics
# (scene_haptics_test.cc, README) and review `git diff tests/golden` before committing.
# Usage: scripts/update-golden.sh [build dir, default build]
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build="${1:-$here/build}"
cmake --build "$build" --target app_tests spidarcad
SPIDARCAD_UPDATE_GOLDEN=1 "$build/tests/app_tests" --gtest_filter='Regression.*'
git -C "$here" status --short tests/golden
