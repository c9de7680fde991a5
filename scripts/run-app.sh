#!/usr/bin/env bash
# Quick start 1: install, build, and open spidarcad on its defaults (demo scene, simulated
# SPIDAR-G). Extra arguments go to spidarcad (e.g. `scripts/run-app.sh fk --help`).
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
"$here/scripts/setup.sh"
exec "$here/build/app/spidarcad" "$@"
