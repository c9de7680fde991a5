#!/usr/bin/env bash
# Quick start 2: install, build, and run every test. The window tests run under a virtual
# X display (Xvfb), so no screen is needed.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
"$here/scripts/setup.sh"
cd "$here/build"
jobs="$(nproc)"
if command -v xvfb-run >/dev/null 2>&1; then
  xvfb-run -a -s "-screen 0 1280x1024x24" ctest --output-on-failure -j "$jobs" "$@"
else
  ctest --output-on-failure -j "$jobs" "$@"
fi
