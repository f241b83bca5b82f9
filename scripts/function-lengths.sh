#!/usr/bin/env bash
# The functions of src/, apps/ and python/ longer than a limit, measured by Universal Ctags (each
# function's first and last line; a lambda is counted on its own, named "(lambda)").
#   bash scripts/function-lengths.sh [LIMIT]          lists "LINES FILE FUNCTION", longest first
#   bash scripts/function-lengths.sh --check [LIMIT]  fails where a function passes LIMIT (150) and is
#       not in scripts/long-functions.txt, or is longer than that list says: the list may only shrink
set -euo pipefail
cd "$(dirname "$0")/.."
check=0
if [ "${1:-}" = "--check" ]; then check=1; shift; fi
limit=${1:-150}
command -v ctags > /dev/null || { echo "function-lengths: Universal Ctags is needed (bash scripts/install-deps.sh)"; exit 2; }
measured=$(git ls-files 'src/*' 'apps/*' 'python/*' | grep -E '\.(cpp|hpp|h|cxx)$' |
  ctags -L - --languages=C++ --kinds-C++=f --fields=+ne -f - 2> /dev/null |
  awk -F'\t' -v limit="$limit" '{
      line = ""; end = "";
      for (i = 4; i <= NF; i++) { if ($i ~ /^line:/) line = substr($i, 6); if ($i ~ /^end:/) end = substr($i, 5) }
      name = $1; if (name ~ /^__anon/) name = "(lambda)";
      if (line != "" && end != "" && end - line + 1 > limit) print end - line + 1, $2, name }' | sort -k1,1rn -k2 -k3)
if [ "$check" -eq 0 ]; then
  [ -n "$measured" ] && echo "$measured"
  exit 0
fi
allowed=scripts/long-functions.txt
status=0
while read -r lines file name; do
  [ -n "$lines" ] || continue
  most=$(awk -v f="$file" -v n="$name" '$2 == f && $3 == n { if ($1 > m) m = $1 } END { print m + 0 }' "$allowed")
  if [ "$most" -eq 0 ]; then
    echo "function-lengths: $file: $name is $lines lines (at most $limit; split it into phases)"; status=1
  elif [ "$lines" -gt "$most" ]; then
    echo "function-lengths: $file: $name grew to $lines lines (scripts/long-functions.txt allows $most)"; status=1
  fi
done <<< "$measured"
count=$(grep -cv '^#' "$allowed" || true)
[ "$status" -eq 0 ] && echo "function-lengths: no function over $limit lines in src/, apps/, python/ but the $count listed in $allowed, none longer than listed"
exit "$status"
