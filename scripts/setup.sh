#!/usr/bin/env bash
# Installs what spidarcad needs from Debian 12 packages (only what is missing) and builds it
# into ./build. Sourced by run-app.sh and run-tests.sh; safe to run again.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
packages=(
  build-essential cmake ninja-build pkg-config ccache
  libeigen3-dev libsuitesparse-dev libopenblas-dev
  libvtk9-dev libcgal-dev libtet1.5-dev zlib1g-dev
  libglfw3-dev libimgui-dev libusb-1.0-0-dev
  nlohmann-json3-dev libcli11-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  xvfb xauth
)
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if ((${#missing[@]})); then
  echo "spidarcad setup: installing ${missing[*]}"
  sudo_cmd=()
  [ "$(id -u)" -eq 0 ] || sudo_cmd=(sudo)
  "${sudo_cmd[@]}" apt-get update -qq
  DEBIAN_FRONTEND=noninteractive "${sudo_cmd[@]}" apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi
build_type="${SPIDARCAD_BUILD_TYPE:-RelWithDebInfo}"
# ccache keeps the compiled objects between builds; with its base directory at the checkout's
# root the compile commands hold relative paths, so a second checkout (a CI clone) reuses them.
export CCACHE_BASEDIR="${CCACHE_BASEDIR:-$here}"
# ccache hashes the working directory into every -g compile unless told not to, which made
# a second checkout (a CI clone, a worktree) miss every object; its debug info then names
# the directory of the checkout that compiled the object first.
export CCACHE_NOHASHDIR="${CCACHE_NOHASHDIR:-1}"
# SPIDARCAD_WERROR=ON (CI) makes compiler warnings errors. Unset, the build keeps what it was
# configured with (OFF in a new build), so run-app.sh after a CI-style run-tests.sh reuses that
# build instead of compiling everything again with other flags.
werror=()
[ -z "${SPIDARCAD_WERROR:-}" ] || werror=(-DSPIDARCAD_WERROR="$SPIDARCAD_WERROR")
cmake -S "$here" -B "$here/build" -G Ninja -DCMAKE_BUILD_TYPE="$build_type" \
  -DCMAKE_CXX_COMPILER_LAUNCHER=ccache -DCMAKE_C_COMPILER_LAUNCHER=ccache \
  "${werror[@]}" >/dev/null
cmake --build "$here/build" -j "$(nproc)"
