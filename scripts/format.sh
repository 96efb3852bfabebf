#!/usr/bin/env bash
# clang-format (.clang-format) over the project's C++ sources.
#   scripts/format.sh           # formats every tracked .cc / .h in place
#   scripts/format.sh --check   # lists the files that are not formatted; exit 1 if any
set -euo pipefail
cd "$(dirname "$0")/.."
CLANG_FORMAT=${CLANG_FORMAT:-clang-format}
command -v "$CLANG_FORMAT" >/dev/null || { echo "format.sh: $CLANG_FORMAT not found (Debian: clang-format)" >&2; exit 2; }
mapfile -t files < <(git ls-files '*.cc' '*.h' 2>/dev/null || find server clients tests tools bench fuzz -name '*.cc' -o -name '*.h')
if [[ ${1:-} == --check ]]; then
  bad=0
  for f in "${files[@]}"; do
    if ! "$CLANG_FORMAT" --dry-run -Werror "$f" >/dev/null 2>&1; then
      echo "not formatted: $f (scripts/format.sh formats it)"
      bad=1
    fi
  done
  exit $bad
fi
"$CLANG_FORMAT" -i "${files[@]}"
