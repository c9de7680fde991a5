#!/bin/bash
# Times `spidarcad fem --cache-dir` on the platform as a user would run it: one piece, slabs
# without the cache, the first run with an empty cache directory, a second run on the same scene,
# then the scene with its load holes widened (r 4 -> 4.5 mm, in the last slab) and with its bolt
# holes widened (r 5.5 -> 6 mm, in the first slab), each reading what the runs before left.
# Prints a markdown table: wall time of the whole command, what it read and what it computed.
#
#   bench/fem_cache_cli.sh [ORDER] [RESOLUTION] [BUILD_DIR]     (defaults: 2 0.01 build)
#
# Needs python3 (to read the JSON). Writes its scenes and cache under a temporary directory,
# removed at the end.
# Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
set -euo pipefail
order=${1:-2}
resolution=${2:-0.01}
build=${3:-build}
here=$(cd "$(dirname "$0")/.." && pwd)
spidarcad=$(cd "$build" && pwd)/app/spidarcad
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

python3 - "$here/assets/scenes/platform.json" "$work" <<'PY'
import sys
text = open(sys.argv[1]).read()
load = '"id": "load_hole", "radius": 0.004'
bolt = '"name": "M10 clearance hole", "radius": 0.0055'
assert load in text and bolt in text, "platform.json changed: update bench/fem_cache_cli.sh"
open(sys.argv[2] + "/platform.json", "w").write(text)
open(sys.argv[2] + "/load_holes.json", "w").write(text.replace(load, load.replace("0.004", "0.0045")))
open(sys.argv[2] + "/bolt_holes.json", "w").write(text.replace(bolt, bolt.replace("0.0055", "0.006")))
PY

common=(--order "$order" --resolution "$resolution" --fix=-1,-1,-1,0.0005,1,1
        --load 0.3,0.1,0.2 --force 0,0,-100 --out "$work/out.vtu")
echo "spidarcad fem, platform, order $order, cell $resolution m, $(nproc) cores, $(date -u +%FT%TZ)"
echo
echo "| run | wall s | read from the cache | computed | cache read s (summed) | write s | tip u_z m |"
echo "|---|---|---|---|---|---|---|"
run() {
  local name=$1 scene=$2
  shift 2
  local start end
  start=$(date +%s.%N)
  "$spidarcad" fem "$work/$scene" "${common[@]}" "$@" > "$work/run.json"
  end=$(date +%s.%N)
  python3 - "$work/run.json" "$name" "$start" "$end" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
c = r.get("cache", {})
s = r.get("substructure", {})
wall = float(sys.argv[4]) - float(sys.argv[3])
def short(items):
    # "3 slab meshes, 3 block factors, 2 plane factors" (and the surface, always computed)
    counts = [(sum(1 for i in items if i.startswith(k)), name) for k, name in
              (("slab", "slab mesh"), ("block", "block factor"), ("interface", "plane factor"))]
    text = ", ".join(f"{n} {name}" + ("es" if name.endswith("sh") else "s") * (n > 1)
                     for n, name in counts if n)
    return text or "-"
computed = short(c.get("recomputed", [])) if c else "everything"
print(f"| {sys.argv[2]} | {wall:.2f} | {short(c.get('reused', []))} | {computed} | "
      f"{s.get('cache_read_seconds', 0):.2f} | {s.get('cache_write_seconds', 0):.2f} | "
      f"{r['loads'][0]['displacement'][2]:.9e} |")
PY
}
run "one piece" platform.json --slabs 0
run "4 slabs, no cache" platform.json --slabs 4
run "first, empty cache" platform.json --cache-dir "$work/cache"
run "second, same scene" platform.json --cache-dir "$work/cache"
run "load holes widened" load_holes.json --cache-dir "$work/cache"
run "bolt holes widened" bolt_holes.json --cache-dir "$work/cache"
echo
echo "cache directory: $(du -sh "$work/cache" | cut -f1)"
