#!/usr/bin/env bash
# The main job: sets up, builds, starts feedloopd on its embedded default (the simulated
# Cartesian printer), prints the sample part through it with progress, then stops the daemon
# and shows the summary. Usage: scripts/run.sh [GCODE_FILE]
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
cmake -S . -B build-release -G Ninja -DCMAKE_BUILD_TYPE=Release -DFEEDLOOP_TESTS=OFF -DFEEDLOOP_BENCH=OFF >/dev/null
cmake --build build-release -j"$(nproc)" --target feedloopd feedloop

FILE=${1:-examples/gcode/cube20_3layers.gcode}
RUN_DIR=$(mktemp -d -t feedloop-run-XXXXXX)
export RUNTIME_DIRECTORY="$RUN_DIR" STATE_DIRECTORY="$RUN_DIR"
echo "== feedloopd (embedded default: simulated printer), sockets in $RUN_DIR"
build-release/daemon/feedloopd >"$RUN_DIR/feedloopd.log" 2>&1 &
DAEMON=$!
trap 'kill $DAEMON 2>/dev/null || true; wait $DAEMON 2>/dev/null || true' EXIT
for _ in $(seq 100); do [ -S "$RUN_DIR/feedloop.sock" ] && break; sleep 0.05; done
echo "== printing $FILE"
rc=0
build-release/cli/feedloop print "$FILE" || rc=$?
kill -TERM $DAEMON
wait $DAEMON || true
trap - EXIT
echo "== daemon log (last lines)"
tail -n 5 "$RUN_DIR/feedloopd.log"
exit $rc
