#!/usr/bin/env bash
# Fails, listing the files, when any tracked *.h/*.cpp differs from clang-format --style=file
# (.clang-format). Uses Debian's clang-format-14 (scripts/setup.sh installs it) so that every
# machine formats alike; another clang-format version may format differently.
# Fix with: git ls-files -z '*.h' '*.cpp' | xargs -0 clang-format-14 -i --style=file
set -euo pipefail
cd "$(dirname "$0")/.."
format=${CLANG_FORMAT:-clang-format-14}
command -v "$format" >/dev/null || { echo "check_format: $format not found (scripts/setup.sh)" >&2; exit 2; }
"$format" --style=file --dump-config >/dev/null  # a broken .clang-format fails here, not silently
# One clang-format process for all files; --dry-run reports "file:line:col: error: code should
# be clang-formatted" for each difference.
mapfile -t drift < <(git ls-files -z '*.h' '*.cpp' |
  xargs -0 "$format" --style=file --dry-run -Werror 2>&1 |
  sed -n 's/^\(.*\):[0-9]*:[0-9]*: error: code should be clang-formatted.*/\1/p' | sort -u)
if [ ${#drift[@]} -gt 0 ]; then
  echo "check_format: ${#drift[@]} file(s) differ from $format --style=file:" >&2
  printf '  %s\n' "${drift[@]}" >&2
  echo "fix: git ls-files -z '*.h' '*.cpp' | xargs -0 $format -i --style=file" >&2
  exit 1
fi
echo "check_format: $(git ls-files '*.h' '*.cpp' | wc -l) files match $("$format" --version | grep -o 'version [0-9.]*')"
