#!/usr/bin/env bash
# Copies the headline table of a `spidarcad report` run (DIR/summary.md) into README.md,
# between the lines `<!-- report-summary:begin -->` and `<!-- report-summary:end -->`, with a
# link to the full report (DIR/report.md, or the --report FILE the report was written to with
# `spidarcad report --markdown FILE`, relative to the README). Nothing else in the README
# changes. Run from anywhere:
#
#   build/app/spidarcad report --out docs/report --markdown docs/performance.md
#   scripts/update-readme-figures.sh docs/report --report docs/performance.md
#
# Usage: scripts/update-readme-figures.sh DIR [README] [--report FILE]   (README defaults to the
# repository's). Exit status 2 when DIR/summary.md, the report or the markers are missing.
# Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
set -euo pipefail

report=""
args=()
while [[ $# -gt 0 ]]; do
  case "$1" in
    --report) [[ $# -ge 2 ]] || { echo "update-readme-figures: --report needs a FILE" >&2; exit 2; }
              report="$2"; shift 2 ;;
    *) args+=("$1"); shift ;;
  esac
done
set -- "${args[@]+"${args[@]}"}"
if [[ $# -lt 1 || $# -gt 2 || "$1" == "-h" || "$1" == "--help" ]]; then
  sed -n '2,12p' "$0" | sed 's/^# \{0,1\}//'
  [[ $# -ge 1 && ( "$1" == "-h" || "$1" == "--help" ) ]] && exit 0
  exit 2
fi

dir="$1"
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
readme="${2:-$repo/README.md}"
report="${report:-$dir/report.md}"
if [[ ! -f "$report" ]]; then
  echo "update-readme-figures: $report not found: give the report's path with --report FILE" >&2
  exit 2
fi
summary="$dir/summary.md"
begin='<!-- report-summary:begin -->'
end='<!-- report-summary:end -->'

if [[ ! -f "$summary" ]]; then
  echo "update-readme-figures: $summary not found: run 'spidarcad report --out $dir' first" >&2
  exit 2
fi
if [[ ! -f "$readme" ]]; then
  echo "update-readme-figures: $readme not found" >&2
  exit 2
fi
nbegin=$(grep -cxF -- "$begin" "$readme" || true)
nend=$(grep -cxF -- "$end" "$readme" || true)
if [[ "$nbegin" != 1 || "$nend" != 1 ]]; then
  echo "update-readme-figures: $readme needs exactly one line '$begin' and one line '$end'" \
       "(found $nbegin and $nend); add them where the table goes" >&2
  exit 2
fi
if (( $(grep -nxF -- "$begin" "$readme" | cut -d: -f1) > $(grep -nxF -- "$end" "$readme" | cut -d: -f1) )); then
  echo "update-readme-figures: in $readme '$end' comes before '$begin'" >&2
  exit 2
fi

# The report's path as seen from the README's directory.
report_link="$(realpath --relative-to="$(dirname "$(realpath "$readme")")" "$(realpath "$report")")"

block="$(mktemp)"
out="$(mktemp "$(dirname "$readme")/.README.XXXXXX")"
trap 'rm -f "$block" "$out"' EXIT
{
  cat "$summary"
  printf '\nEvery figure with its plot, table and method: [%s](%s).\n' "$report_link" "$report_link"
} > "$block"

awk -v begin="$begin" -v end="$end" -v block="$block" '
  $0 == begin { print; while ((getline line < block) > 0) print line; skipping = 1; next }
  $0 == end { skipping = 0 }
  !skipping { print }
' "$readme" > "$out"
chmod --reference="$readme" "$out"
mv "$out" "$readme"
trap 'rm -f "$block"' EXIT
echo "update-readme-figures: $readme updated from $summary"
