#!/usr/bin/env bash
# Runs clang-tidy-14 (.clang-tidy) with BUILD_DIR/compile_commands.json on every source of the
# libraries and the CLI that the build compiles (src/, identify/, optimize/: 58 files), two files
# at a time. Any finding fails (WarningsAsErrors).
# TIDY_EXCLUDE=REGEX leaves out sources matching it (none by default).
# Usage: [TIDY_EXCLUDE=REGEX] scripts/tidy.sh [BUILD_DIR]   (default: build, configured by setup.sh)
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
build=${1:-$here/build}
[ -f "$build/compile_commands.json" ] || { echo "tidy: no $build/compile_commands.json" >&2; exit 2; }
exclude=${TIDY_EXCLUDE-}
# A file is checked when it is under src/, identify/ or optimize/ and not excluded (Python's re,
# as run-clang-tidy matches its file patterns).
if [ -n "$exclude" ]; then
  files="^$here/(?!($exclude)\.cpp$)(src|identify|optimize)/.*\.cpp$"
else
  files="^$here/(src|identify|optimize)/.*\.cpp$"
fi
count=$(python3 -c 'import json, re, sys
print(sum(1 for e in json.load(open(sys.argv[1])) if re.search(sys.argv[2], e["file"])))' \
  "$build/compile_commands.json" "$files")
if ! run-clang-tidy-14 -quiet -j "$(nproc)" -p "$build" -clang-tidy-binary clang-tidy-14 \
     "$files" > "$build/tidy.log" 2>&1; then
  sed 's/\x1b\[[0-9;]*m//g' "$build/tidy.log" | grep -E "(warning|error):" | sort -u >&2 ||
    cat "$build/tidy.log" >&2
  echo "tidy: findings above (full log $build/tidy.log)" >&2
  exit 1
fi
echo "tidy: $count files clean${exclude:+ (excluded: $exclude)}"
