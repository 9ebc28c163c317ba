#!/usr/bin/env bash
# Runs clang-tidy-14 (.clang-tidy) with BUILD_DIR/compile_commands.json, two files at a time.
# Any finding fails (WarningsAsErrors).
# Scope: CI's 30-minute budget on two cores does not hold all 56 library and CLI sources (each
# parses Eigen, Ceres or SUNDIALS headers: about 10 s of CPU per file, 5 min for all), so by default
# it checks the code that reads untrusted input and the CLI: src/io, the CLI (src/cli) and every
# parser (scene, scene parameters, leveller config and strip table, balancer input, sweep config
# and study input, coupling config, fit config, records: table, COMTRADE, MAT, record spec).
# TIDY_ALL=1 checks every source of the libraries and the CLI (src/, identify/, optimize/).
# Usage: [TIDY_ALL=1] scripts/tidy.sh [BUILD_DIR]   (default: build, configured by setup.sh)
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
build=${1:-$here/build}
[ -f "$build/compile_commands.json" ] || { echo "tidy: no $build/compile_commands.json" >&2; exit 2; }
if [ "${TIDY_ALL:-0}" = 1 ]; then
  files="^$here/(src|identify|optimize)/"
else
  files="^$here/(src/io/.*|src/cli/.*|src/driveline/scene(_parameter)?|src/leveller/(leveller_config|setpoint_table)|src/balancer/balancer_input|src/sweep/(sweep_config|study_input)|optimize/coupling/coupling_config|identify/(fit_config|oscillogram|comtrade|mat_record|record_generator))\.cpp$"
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
echo "tidy: $count files clean"
