#!/usr/bin/env bash
# Builds the test suite and the libFuzzer harnesses with clang-14 and
# -fsanitize=address,undefined (MILLKIT_SANITIZE; UBSan without recovery) in build-asan, -O1
# without debug information (ASan's reports still name functions; build time matters on CI's two
# cores), without benchmarks and examples, and runs every test under the sanitizers. A report
# fails the test that triggers it. Tests' wall-clock guards are 10 times longer in this build
# (tests/support/wall_guard.h). The harnesses share this build (one sanitized build of the
# libraries instead of two); scripts/fuzz.sh runs them.
# Not run here: the package test (label "package"), which installs the build and compiles
# examples/ against it as a client would; a client of sanitized libraries needs the sanitizer
# flags that the package does not pass on, and the plain build's tests run it. Nor the six
# tests that repeat whole simulations or fits over many seeds (the seeded extreme scenes, the
# stiff runs near a switching surface with their CVODE references (14 s plain), the random-lines and three-mass seed sets, the parallel fits of three
# random lines): under the sanitizers they take about 20 minutes of one core (465 s, 405 s,
# 159 s, 106 s, 53 s measured), beyond CI's budget, and every code path they run is run here by
# the other tests; the plain build runs them. Likewise the identification fits beyond five
# representative ones (verdict ok, verdict not_converged, a gap not identifiable, a COMTRADE and
# a MAT record): each takes 20 to 300 s under the sanitizers (measured on a clean-clone run) and
# runs the same fit code on another record or option. And the campaign's repeat on 2 threads, the
# sensitivities' 200 random-line points, and the fits with the statistical stop on and off.
# Without MPI (MILLKIT_WITH_MPI=OFF): OpenMPI's own allocations at MPI_Init would be reported as
# leaks, and the MPI code paths are the plain build's (its mpirun tests); here the tests check that
# a build without MPI refuses to run as several ranks.
# The test suites are compiled at -O1 like the libraries. At -O0 a test file compiles 2.2-2.4
# times faster, but the tests ran 2.6 times slower (2026-12-07): the linker keeps the test
# objects' -O0 copies of every inline function they share with the libraries (Eigen's kernels).
# Usage: scripts/sanitize.sh [BUILD_DIR]   (default: build-asan)
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
build=${1:-$here/build-asan}
cmake -S "$here" -B "$build" -DCMAKE_CXX_COMPILER=clang++-14 -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  "-DCMAKE_CXX_FLAGS_RELWITHDEBINFO=-O1 -g0" -DMILLKIT_SANITIZE=ON \
  -DMILLKIT_BUILD_FUZZERS=ON -DMILLKIT_BUILD_BENCH=OFF -DMILLKIT_BUILD_EXAMPLES=OFF \
  -DMILLKIT_WITH_MPI=OFF >&2
cmake --build "$build" -j "$(nproc)" >&2
cd "$build"
# allocator_may_return_null: an impossible allocation throws std::bad_alloc as it does without
# ASan (which otherwise aborts on it).
export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:strict_string_checks=1:check_initialization_order=1:allocator_may_return_null=1}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
slow="Seeded extreme scenes|Stiff runs whose switching surfaces stay near zero|random lines: a fixed sample|three-mass line: every seed"
slow+="|three-mass line: the record printed|parallel fit: random lines"
slow+="|identify without a config on the bundled record|logger time: a record shifted"
slow+="|identify takes --data more than once|identify fits the bundled record and writes"
slow+="|Records at 1 and 10 kHz|identify reads a .mat record with logger time"
slow+="|A second noisy record shrinks|verdict misfit|identify reports a gap the record cannot tell"
slow+="|Modelling the recorder's anti-alias filter|a record in kN|Two noise-free records give back"
slow+="|parameters correlated with one not identifiable|a gain held by its bounds|a logger CSV with BOM|A noise-free record gives back every true"
slow+="|identify --threads 2 and the default write the same JSON|Over 20 noisy records"
# Random line 9661's two fits (5 s each in the plain build, the second search's 12 starts): the
# bound walk runs here in "A parameter at its bound has its profile followed inward".
slow+="|a parameter within 2 standard errors of a bound is walked inward"
# Five extreme scenes held within roundoff of a switching surface, each with its denser run and
# its CVODE references (1.3 s plain): the stiff substeps' code runs here in the other stiff tests.
slow+="|A surface held within roundoff of zero by a heavily damped motion is crossed"
# The campaign run twice to compare 1 and 2 threads: 27 s under the sanitizers; the other campaign
# tests run the same fits once (35 s).
slow+="|a campaign gives the same table and trends on 1 and 2 threads"
# The sensitivities against central differences at 200 random-line points (59 s under the
# sanitizers) and at the bundled scenes' 36 points (82 s on the run of 2026-11-27, the stage's
# longest test): the pass runs here on three of those scenes and six random lines under every
# contact law and parameter kind, attached and replayed ("Sensitivities along a kept run"), and
# through a recorder low-pass against central differences (two tests).
slow+="|Sensitivities agree with central differences at 200 points"
slow+="|Sensitivities agree with central differences on the bundled scenes"
# Six random-line fits with the statistical stop on and off: 86 s under the sanitizers. Every fit
# here runs the stop; its measure has its own fast test.
slow+="|Fits with and without the remaining-step stop agree"
# The same with the rejoin stop on and off; the search's own test runs the stop on three lines.
slow+="|Fits with and without the rejoin stop agree"
# Whole fits whose code the other fits here run too (keeping the stage under CI's budget):
# shards merged against one run (41 s; the shard and merge errors have their own tests), the
# bundled record's verdict ok (38 s), random line 393's verdict (22 s).
slow+="|shards 1/2 and 2/2 merged write the same table|verdict ok: the bundled scene on its own"
slow+="|verdict not_converged: a best minimum that only a basin hop reached"
# Random lines 555, 526, 765, 712 and 378, each fitted twice, with and without the relaxed
# profile probes, the curved-valley walks or the second search; the search's own tests run both
# walks under the sanitizers. Random line 8395 fitted twice (with and without the 4 % gap kicks;
# 5 s in the Release build) and stiffness line 7832 once (its two searches, 3 s): the kicks' own
# points are tested here (multistart_test.cpp), and the walks run in the other fits.
slow+="|a gap kicked two valleys of its impact timing away|search: a curved valley is followed where its direction meets"
slow+="|standard errors: a valley that curves away from the straight profile"
slow+="|verdict not_converged: a lower valley found along a sharply curved one"
slow+="|standard errors: a profile whose valley bends sharply is followed"
slow+="|standard errors: a profile that bends 10 to 30 times the prediction is followed"
slow+="|verdict ok: starts scattered over many valleys run the search again"
# Random line 8708 (wide prior) fitted twice, with and without the second search (15 s in the
# Release build, the 413 line included): the second search's trigger runs in every fit here.
slow+="|verdict ok: a wrong valley that half the starts reach runs the search again"
# Random line 384 under the no_pull law fitted twice, with and without going on from a profile
# probe below the minimum (the same GoOnBelowBest as the search's axis-probe restarts).
slow+="|verdict ok: a profile probe below the minimum is gone on from"
# Random line 2084's one fit, 176 s under the sanitizers (the longest test here; the clean-clone
# CI run of 2026-11-27 took 1772 s of the 30 minutes): the widening of a correlated parameter it
# checks runs in the other widened fits here (the flatter profile, the walks' held points), and
# its covariance update (WidenAlongProfiles) has its own test (multistart_test.cpp).
# Random line 393 fitted twice, with and without the gap kicks: 64 s under the sanitizers, the
# longest left (clean-clone run of 2026-11-27); every fit here runs the kicks (GapKicks and their
# refinement with the rejoin stop), and "an iteration limit of 1" keeps a not_converged verdict.
# Random line 34 under no_pull, whose starts stop on the rough floor of the best's valley: one
# whole fit (about 1.5 s plain); its rule (verdict.cpp) runs in every fit here.
# Two whole random-line fits of the standard errors' widening (2026-11-27, a slow hour: 60 and 43 s
# under the sanitizers, the stage's longest after the bundled scenes' sensitivities; the run took
# 1961 s of the 30 minutes): a flatter profile followed, and the walks' held points widening what
# they move. The walks and the widening keep their own tests here (a profile that curves away, a
# held point widens what it moved, widening what is correlated, a bound's profile followed inward).
slow+="|standard errors: a profile a little flatter than its linearisation at 2 SE is followed"
slow+="|standard errors: points held on walks widen every parameter they move"
slow+="|standard errors: what is correlated with a widened parameter widens with it"
slow+="|verdict not_converged: a gap kicked into the next valley"
slow+="|verdict ok: starts that stopped on the rough floor"
# Random line 12024 fitted twice, with and without the creep stop (119 s under the sanitizers on
# the clean-clone run of 2026-12-06, a slow hour: 1745 s of the 30 minutes), and random line
# 12121's one fit (45 s): every fit here runs the creep stop (CloseEnough) and its floor
# (FloorCost); the plain build runs both lines.
slow+="|verdict ok: Levenberg-Marquardt creeping along the floor ends there"
slow+="|verdict ok: a probe lower only by the creep stop's slack is not a lower point"
# The random-line generator's variants over 20 seeds (33 s under the sanitizers, the stage's
# longest test on 2026-11-28): test support that synthesizes records with the simulation code
# every other test here runs; the plain build runs it.
slow+="|random line variants change only what they name"
# Random line 91 fitted eight times from four wrong-valley starts, with and without the held open
# gap (134 s under the sanitizers on the clean-clone run of e59a3e9, the stage's longest), and
# random line 9326 fitted twice, with and without the gap held across its range (39 s). The
# points they hold are refined by the same held refits as every walk here ("A gap is held across
# its range" checks the gap's held points). The open gap's edge (OpenGapEdge, found only for a gap
# the record hardly depends on) may run only in these two: ten evaluations of the same
# ProjectedCost every fit here calls, on a copy of the point; the plain build runs both.
slow+="|verdict not_converged: a gap left open at a minimum is held below where it closes"
slow+="|standard errors: a gap's second valley behind a wall is found across its range"
ctest --output-on-failure -j "$(nproc)" -LE package -E "$slow"
