#!/usr/bin/env bash
# Sets up, builds and runs every test. Two builds (docs/decisions.md, "CI time"):
#   1. GCC, -O2: every test, the slow ones included (timing and allocation tests run
#      here, where no sanitizer changes the allocator or the speed);
#   2. clang, ASan + UBSan (libFuzzer's coverage in the input modules), compiled at nice 19 while
#      build 1's tests run: the tests again under the sanitizers (without the slow, wall-clock,
#      allocation-counting and numerical ones), then a short run of every fuzz target from the
#      same build.
# Both builds compile with precompiled headers (FEEDLOOP_PCH, on by default).
# Usage: scripts/test.sh [--fast]  (--fast: build 1 only, every test program built and run in it)
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
JOBS=$(nproc)
t0=$SECONDS
stage() { echo "== $1 (at $(( (SECONDS - t0) / 60 )) min $(( (SECONDS - t0) % 60 )) s)"; }

stage "build 1: GCC -O2"
# No debug info in this build (-g1, line tables only, cost ~13 % of its compile time: a paired
# sample of 6 units, docs/decisions.md "CI time"); gtest's failures carry their file and line
# without it. The sanitizer build keeps -g1: its reports name the lines.
fast=0
if [ "${1:-}" = "--fast" ]; then fast=1; fi
# With the sanitizer build to follow, this build leaves out the test programs whose every case the
# sanitizer stage runs: each test program then runs once, and this build compiles 31 % less
# (docs/decisions.md, "CI time: each test program runs once"). --fast builds and runs them all here.
all_tests=OFF
if [ $fast = 1 ]; then all_tests=ON; fi
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release -DCMAKE_CXX_FLAGS_RELEASE="-O2 -DNDEBUG" \
  -DFEEDLOOP_ALL_TESTS_IN_ALL=$all_tests >/dev/null
cmake --build build -j"$JOBS"

if [ $fast = 0 ]; then
  # Build 2 compiles in the background at nice 19 while build 1's tests run: the wall-clock tests
  # leave the cores mostly idle (they wait on the clock), and at nice 19 the compilers take only
  # what the tests leave (a nice-0 task outweighs a nice-19 one 68 to 1). It is the same session
  # and process group as this script (a new session would get its own scheduler autogroup, where
  # nice no longer ranks it below the tests). The wall-clock tests so run beside a load, as the
  # README's main job must (docs/decisions.md, "CI time").
  # -O1: sanitizers keep full precision; the plant simulator and fits stay fast enough to test.
  # Only what this stage runs is built (target sanitizer_tests): the tests not labelled
  # slow/realtime/long/browser/alloc/numeric, the programs they start, the fuzz targets. The
  # wall-clock tests run in build 1 only; their code paths run here in the virtual-time tests and
  # the fuzz targets of the daemon's channels; the numerical modules run here inside the machine
  # tests (docs/decisions.md, "CI time").
  stage "build 2 in the background: clang, ASan + UBSan + libFuzzer coverage (log: build-san/build.log)"
  cmake -S . -B build-san -G Ninja -DCMAKE_CXX_COMPILER=clang++ -DCMAKE_BUILD_TYPE=Debug \
    -DCMAKE_CXX_FLAGS_DEBUG="-O1 -g1" -DFEEDLOOP_SANITIZE=ON -DFEEDLOOP_FUZZ=ON -DFEEDLOOP_BENCH=OFF >/dev/null
  # ninja itself (not cmake --build) so that the trap's SIGTERM reaches it and it stops its jobs.
  nice -n 19 ninja -C build-san -j"$JOBS" sanitizer_tests >build-san/build.log 2>&1 &
  build2_pid=$!
  trap 'kill "$build2_pid" 2>/dev/null || true' EXIT
fi

# Tests labelled `realtime` run a daemon or a serial link on the wall clock: they run one at a
# time after the others, so that no other test competes with their threads at the same priority
# (build 2's compilers run beside them at nice 19).
# Tests labelled `long` (the whole corpus on the simulated printer, ~15 min of CPU; the two
# whole-benchy prints, ~5 min) are not run here: `ctest --test-dir build -L long` (README).
# -E _NOT_BUILT: the placeholders ctest keeps for the programs this build left out (above).
stage "tests"
ctest --test-dir build -j"$JOBS" --output-on-failure --timeout 600 -LE "realtime|long|browser" -E _NOT_BUILT
stage "tests on the wall clock, one at a time"
ctest --test-dir build --output-on-failure --timeout 600 -L realtime -LE "long|browser"

if [ $fast = 1 ]; then exit 0; fi

stage "build 2: waiting for it to finish"
if ! wait "$build2_pid"; then
  tail -n 60 build-san/build.log
  echo "build 2 failed (whole log: build-san/build.log)"
  exit 1
fi
trap - EXIT
tail -n 1 build-san/build.log
stage "tests under sanitizers"
export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1
# -E _NOT_BUILT: the placeholders ctest keeps for the test programs this stage did not build.
# fuzz_replay: the corpus replay tests, not built here: the fuzz stage below runs every corpus file.
ctest --test-dir build-san -j"$JOBS" --output-on-failure --timeout 900 -LE "slow|realtime|long|browser|fuzz_replay|alloc|numeric" -E _NOT_BUILT

stage "fuzz (short run of every target)"
bash fuzz/run.sh build-san 5  # fuzz/README.md; 5 s each (the long runs are separate)
stage "done"
