#!/usr/bin/env bash
# Checks the relative links of README.md and docs/**/*.md: each must point to a file or folder
# inside the repository, and an anchor into a Markdown file (file.md#section) must match one of
# its headings (GitHub's rule: lower case, punctuation dropped, spaces to hyphens) or <a id> tags.
# Usage: scripts/check-doc-links.sh   (prints one line per broken link and exits 1)
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
root="$PWD"
slugs() {  # the anchors of a Markdown file's headings and its <a id="..."> tags, one per line
  grep -E '^#{1,6} ' "$1" | sed -E 's/^#+ +//' | tr 'A-Z' 'a-z' |
    sed -E 's/[][`*_.,:;!?()/\\"'"'"'+=<>|{}~&@$%^]//g; s/ /-/g'
  grep -oE '<a id="[^"]+"' "$1" | sed -E 's/^<a id="//; s/"$//' || true
}
status=0
while IFS= read -r doc; do
  dir="$(dirname "$doc")"
  while IFS= read -r target; do
    case "$target" in http://* | https://* | mailto:*) continue ;; esac
    path="${target%%#*}"
    anchor=""
    [[ "$target" == *"#"* ]] && anchor="${target#*#}"
    if [ -z "$path" ]; then file="$doc"; else file="$(realpath -m "$dir/$path")"; fi
    case "$(realpath -m "$file")" in
      "$root"/*) ;;
      *) echo "$doc: link leaves the repository: $target"; status=1; continue ;;
    esac
    if [ ! -e "$file" ]; then echo "$doc: broken link: $target"; status=1; continue; fi
    if [ -n "$anchor" ] && [[ "$file" == *.md ]] && ! slugs "$file" | grep -qxF "$anchor"; then
      echo "$doc: no heading for anchor: $target"; status=1
    fi
  done < <(grep -o '](\([^)]*\))' "$doc" | sed 's/^](//; s/)$//')
done < <(find README.md docs -name '*.md' | sort)
exit "$status"
