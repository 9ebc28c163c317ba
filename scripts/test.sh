#!/usr/bin/env bash
# Sets up (packages, configure, build) and runs the whole test suite, then the checks CI adds:
# format drift (check_format.sh), clang-tidy (tidy.sh), the tests under ASan+UBSan
# (sanitize.sh, build-asan) and a short libFuzzer run of every harness (fuzz.sh). The plain tests
# run first. Each stage prints its time. STAGES picks the extra checks (default: format and tidy;
# all four: STAGES="format tidy sanitize fuzz" scripts/test.sh; STAGES= for the plain build and
# tests only).
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
build=${BUILD_DIR:-$here/build}
asan_build=${ASAN_BUILD_DIR:-$here/build-asan}
stages=${STAGES-format tidy}

stage() {
  local name=$1
  shift
  local start=$SECONDS
  echo "== $name" >&2
  "$@"
  echo "== $name: $((SECONDS - start)) s" >&2
}

stage "setup and build" "$here/scripts/setup.sh" "$build"
stage "tests" bash -c "cd '$build' && ctest --output-on-failure -j $(nproc)"
for s in $stages; do
  case $s in
    format) stage "format" "$here/scripts/check_format.sh" ;;
    tidy) stage "clang-tidy" "$here/scripts/tidy.sh" "$build" ;;
    sanitize) stage "ASan+UBSan build and tests" "$here/scripts/sanitize.sh" "$asan_build" ;;
    fuzz) stage "fuzzing" "$here/scripts/fuzz.sh" "$asan_build" ;;
    *) echo "test.sh: unknown stage '$s'" >&2; exit 2 ;;
  esac
done
echo "== all stages passed in $SECONDS s" >&2
