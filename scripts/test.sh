#!/usr/bin/env bash
# Sets up, builds and runs every test: the normal build, the ASan+UBSan build, and a short fuzz
# run of the G-code parser. Usage: scripts/test.sh [--fast]  (--fast: normal build only)
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
JOBS=$(nproc)

echo "== build (RelWithDebInfo)"
# -g1 (line tables only) in every build here: full debug info cost ~38 % of the compile time
# (docs/decisions.md, "CI time"); stack traces and sanitizer reports keep their lines.
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O2 -g1 -DNDEBUG" >/dev/null
cmake --build build -j"$JOBS"
echo "== tests"
ctest --test-dir build -j"$JOBS" --output-on-failure --timeout 600

if [ "${1:-}" = "--fast" ]; then exit 0; fi

echo "== build (ASan + UBSan)"
# -O1: sanitizers keep full precision; the plant simulator and fits stay fast enough to test.
cmake -S . -B build-asan -G Ninja -DCMAKE_BUILD_TYPE=Debug -DCMAKE_CXX_FLAGS_DEBUG="-O1 -g1" \
  -DFEEDLOOP_SANITIZE=ON -DFEEDLOOP_BENCH=OFF >/dev/null
cmake --build build-asan -j"$JOBS"
echo "== tests under sanitizers"
ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1 \
  ctest --test-dir build-asan -j"$JOBS" --output-on-failure --timeout 900 -LE slow

if [ -f fuzz/CMakeLists.txt ]; then
  echo "== fuzz (short run)"
  cmake -S . -B build-fuzz -G Ninja -DCMAKE_CXX_COMPILER=clang++ -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O2 -g1 -DNDEBUG" \
    -DFEEDLOOP_FUZZ=ON -DFEEDLOOP_TESTS=OFF -DFEEDLOOP_BENCH=OFF >/dev/null
  cmake --build build-fuzz -j"$JOBS" --target fuzz_all
  bash fuzz/run.sh build-fuzz 20  # every target (fuzz/README.md), 20 s each
fi
