#!/usr/bin/env bash
# The main job: sets up, builds, starts feedloopd on its embedded default (the simulated
# Cartesian printer), prints the sample part through it with progress, then stops the daemon
# and shows the summary. Usage: scripts/run.sh [GCODE_FILE]
# FEEDLOOP_CONFIG=FILE runs that config instead (e.g. config/examples/cartesian_sim_web.yaml, which
# turns the web UI on: the Mainsail/Fluidd builds are unpacked from ../shared/webui/ and the URL is
# printed; docs/web.md).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
cmake -S . -B build-release -G Ninja -DCMAKE_BUILD_TYPE=Release -DFEEDLOOP_TESTS=OFF -DFEEDLOOP_BENCH=OFF >/dev/null
cmake --build build-release -j"$(nproc)" --target feedloopd feedloop

FILE=${1:-examples/gcode/cube20_3layers.gcode}
RUN_DIR=$(mktemp -d -t feedloop-run-XXXXXX)
export RUNTIME_DIRECTORY="$RUN_DIR" STATE_DIRECTORY="$RUN_DIR"
CONFIG_ARGS=()
if [ -n "${FEEDLOOP_CONFIG:-}" ]; then
  CONFIG_ARGS=(--config "$FEEDLOOP_CONFIG")
  if grep -q "build/webui/" "$FEEDLOOP_CONFIG" && [ -f ../shared/webui/mainsail.tar.xz ]; then
    for ui in mainsail fluidd; do
      [ -f "build/webui/$ui/index.html" ] || { mkdir -p "build/webui/$ui" && tar -xJf "../shared/webui/$ui.tar.xz" -C "build/webui/$ui"; }
    done
  fi
  echo "== feedloopd ($FEEDLOOP_CONFIG), sockets in $RUN_DIR"
else
  echo "== feedloopd (embedded default: simulated printer), sockets in $RUN_DIR"
fi
build-release/daemon/feedloopd "${CONFIG_ARGS[@]}" >"$RUN_DIR/feedloopd.log" 2>&1 &
DAEMON=$!
trap 'kill $DAEMON 2>/dev/null || true; wait $DAEMON 2>/dev/null || true' EXIT
for _ in $(seq 100); do [ -S "$RUN_DIR/feedloop.sock" ] && break; sleep 0.05; done
# The web UI (web.enabled in the config): its URL, from the daemon's log.
if url=$(grep -o "web: http://[^ ]*" "$RUN_DIR/feedloopd.log"); then
  echo "== web UI: ${url#web: } (feedloop's page: ${url#web: }server/feedloop/page/)"
fi
echo "== printing $FILE"
rc=0
build-release/cli/feedloop print "$FILE" || rc=$?
kill -TERM $DAEMON
wait $DAEMON || true
trap - EXIT
echo "== daemon log (last lines)"
tail -n 5 "$RUN_DIR/feedloopd.log"
exit $rc
