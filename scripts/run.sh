#!/usr/bin/env bash
# The main job on the bundled data: sets up (packages, configure, build), then fits the bundled
# two-spindle oscillogram (datasets/records/mill5_two_spindles.csv) to the five-mass scene: damping,
# backlash, spindle stiffness, bite time, gain and offset per channel. Prints the parameter table;
# writes out/fit.json (values, standard errors, correlations, identifiability), out/fit.csv
# (measured, fitted, residual) and out/fit.svg (plot).
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
build=${BUILD_DIR:-$here/build}
"$here/scripts/setup.sh" "$build"
mkdir -p "$here/out"
"$build/src/cli/millkit" identify "$here/datasets/scenes/mill5_bite.toml" \
  --data "$here/datasets/records/mill5_two_spindles.csv" \
  --config "$here/datasets/records/mill5_two_spindles.fit.toml" \
  --out "$here/out/fit.json" --trace "$here/out/fit.csv" --plot "$here/out/fit.svg"
echo "fit written to out/fit.json, out/fit.csv, out/fit.svg" >&2
