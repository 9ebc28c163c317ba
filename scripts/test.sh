#!/usr/bin/env bash
# Sets up (packages, configure, build) and runs the whole test suite, then the checks CI adds:
# format drift (check_format.sh), clang-tidy on the library and CLI sources (tidy.sh), the tests
# under ASan+UBSan (sanitize.sh: clang-14, build-asan, which also builds the libFuzzer harnesses)
# and a short libFuzzer run of every parser harness (fuzz.sh, 5 s each). The plain tests run
# first. Each stage prints its time; a failing stage does not stop the later ones, and the run
# ends with the list of failed stages and exit 1. STAGES picks the extra checks (default all
# four, "format tidy sanitize fuzz"; STAGES= for the plain build and tests only); fuzz runs the
# harnesses that sanitize built (ASAN_BUILD_DIR).
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
build=${BUILD_DIR:-$here/build}
asan_build=${ASAN_BUILD_DIR:-$here/build-asan}
stages=${STAGES-format tidy sanitize fuzz}

failed=()
# A stage that fails is reported and the next one still runs (one CI run shows every failing
# check); the plain build must succeed for anything after it to run.
stage() {
  local name=$1
  shift
  local start=$SECONDS
  echo "== $name" >&2
  if "$@"; then
    echo "== $name: $((SECONDS - start)) s" >&2
  else
    echo "== $name: FAILED after $((SECONDS - start)) s" >&2
    failed+=("$name")
  fi
}

echo "== setup and build" >&2
if ! "$here/scripts/setup.sh" "$build"; then
  echo "== setup and build: FAILED after $SECONDS s" >&2
  exit 1
fi
echo "== setup and build: $SECONDS s" >&2
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
if [ ${#failed[@]} -gt 0 ]; then
  echo "== failed: ${failed[*]} (after $SECONDS s)" >&2
  exit 1
fi
echo "== all stages passed in $SECONDS s" >&2
