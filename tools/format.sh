#!/usr/bin/env bash
# The tree's C++ in the committed style (.clang-format, Debian 12's clang-format 14).
#   tools/format.sh          reformat every tracked .cpp/.h in place
#   tools/format.sh --check  list the files that differ and fail if any does (CI)
set -euo pipefail
cd "$(dirname "$0")/.."
command -v clang-format >/dev/null || { echo "format.sh: clang-format is not installed (apt-get install clang-format)" >&2; exit 2; }
mapfile -t files < <(git ls-files '*.cpp' '*.h')
if [[ "${1:-}" == "--check" ]]; then
  bad=0
  for f in "${files[@]}"; do
    if ! clang-format --dry-run -Werror "$f" >/dev/null 2>&1; then
      echo "format.sh: $f differs from .clang-format (run tools/format.sh)" >&2
      bad=$((bad + 1))
    fi
  done
  if ((bad > 0)); then
    echo "format.sh: $bad of ${#files[@]} files differ" >&2
    exit 1
  fi
  echo "format.sh: ${#files[@]} files in style"
else
  clang-format -i "${files[@]}"
fi
