#!/usr/bin/env bash
# The main job on the bundled data: sets up (packages, configure, build), simulates the bundled
# five-mass bite scene and prints its dynamic-factor table. Results go to out/.
# (Identification of the bundled oscillogram, issue 3, will become the main job when it lands.)
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
build=${BUILD_DIR:-$here/build}
"$here/scripts/setup.sh" "$build"
mkdir -p "$here/out"
"$build/src/cli/millkit" simulate "$here/datasets/scenes/mill5_bite.toml" \
  --out "$here/out/mill5_bite.csv"
echo "time series written to out/mill5_bite.csv" >&2
