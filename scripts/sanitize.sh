#!/usr/bin/env bash
# Builds the test suite and the libFuzzer harnesses with clang-14 and
# -fsanitize=address,undefined (MILLKIT_SANITIZE; UBSan without recovery) in build-asan, -O1 with
# line tables, and runs every test under the sanitizers. A report fails the test that triggers it.
# The harnesses share this build (one sanitized build of the libraries instead of two on CI's two
# cores); scripts/fuzz.sh runs them.
# Usage: scripts/sanitize.sh [BUILD_DIR]   (default: build-asan)
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
build=${1:-$here/build-asan}
cmake -S "$here" -B "$build" -DCMAKE_CXX_COMPILER=clang++-14 -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  "-DCMAKE_CXX_FLAGS_RELWITHDEBINFO=-O1 -gline-tables-only" -DMILLKIT_SANITIZE=ON \
  -DMILLKIT_BUILD_FUZZERS=ON -DMILLKIT_BUILD_BENCH=OFF >&2
cmake --build "$build" -j "$(nproc)" >&2
cd "$build"
# allocator_may_return_null: an impossible allocation throws std::bad_alloc as it does without
# ASan (which otherwise aborts on it).
export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:strict_string_checks=1:check_initialization_order=1:allocator_may_return_null=1}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
ctest --output-on-failure -j "$(nproc)"
