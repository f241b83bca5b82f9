#!/usr/bin/env bash
# Checks that every C++ source in the tree is formatted by clang-format (.clang-format: Google style,
# 120 columns). With --fix, formats them in place instead.
#   bash scripts/check-format.sh [--fix]
set -euo pipefail
cd "$(dirname "$0")/.."
command -v clang-format > /dev/null || { echo "check-format: clang-format is needed (bash scripts/install-deps.sh)"; exit 2; }
mapfile -t files < <(git ls-files '*.cpp' '*.hpp' '*.h' '*.cxx')
if [ "${1:-}" = "--fix" ]; then
  clang-format -i "${files[@]}"
  exit 0
fi
if ! clang-format --dry-run --Werror "${files[@]}" 2> /tmp/csrbf-format.$$; then
  grep -m 20 "error:" /tmp/csrbf-format.$$ || true
  rm -f /tmp/csrbf-format.$$
  echo "check-format: the files above are not formatted; run: bash scripts/check-format.sh --fix"
  exit 1
fi
rm -f /tmp/csrbf-format.$$
echo "check-format: ${#files[@]} files formatted"
