#!/usr/bin/env bash
# Installs feedloop's build and test dependencies from Debian's packages. Idempotent; run as root
# (or with sudo available). Only Debian's archive is contacted.
# Usage: scripts/setup.sh [--optional]
#   without arguments: what the build, the main job and scripts/test.sh need;
#   --optional: also the servo-latency benchmark's and the browser test's packages (below).
set -euo pipefail
WITH_OPTIONAL=0
if [ "${1:-}" = "--optional" ]; then WITH_OPTIONAL=1; fi

PACKAGES=(
  build-essential cmake ninja-build pkg-config git python3
  libeigen3-dev libusb-1.0-0-dev libboost-dev libspdlog-dev libyaml-cpp-dev
  libgtest-dev libgmock-dev libsystemd-dev libfftw3-dev nlohmann-json3-dev
  libsqlite3-dev                      # the web server's database (server.database.*)
  clang libclang-rt-14-dev            # libFuzzer + sanitizer runtimes
  lld                                 # the linker (faster than GNU ld; CMakeLists.txt)
  pronsole                            # the serial host used in the pty test (not `printrun`:
                                      # its GUI parts pull in wxWidgets, GTK and numpy)
  systemd                             # systemd-analyze verify of the unit
  socat xz-utils
  gnuplot-nox                         # the identification report's plots (ident fit --out DIR)
)
OPTIONAL=()
if [ "$WITH_OPTIONAL" = 1 ]; then
  OPTIONAL=(rt-tests stress-ng        # servo-latency benchmark, load runs
    chromium nodejs npm)              # the browser test (ctest -L browser) only
fi

# An optional package counts as present when its command is there: a machine may carry Node.js
# from elsewhere (whose nodejs bundles npm and conflicts with Debian's npm package).
declare -A command_of=([rt-tests]=cyclictest [stress-ng]=stress-ng [chromium]=chromium
  [nodejs]=node [npm]=npm)
missing=() missing_optional=()
for p in "${PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
for p in ${OPTIONAL[@]+"${OPTIONAL[@]}"}; do
  command -v "${command_of[$p]}" >/dev/null 2>&1 ||
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" ||
    missing_optional+=("$p")
done
if [ ${#missing[@]} -eq 0 ] && [ ${#missing_optional[@]} -eq 0 ]; then
  echo "setup: all dependencies present"
  exit 0
fi
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
echo "setup: installing ${missing[*]} ${missing_optional[*]}"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
if [ ${#missing[@]} -gt 0 ]; then
  $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi
# One at a time: a package that cannot be installed here leaves the others installed.
for p in ${missing_optional[@]+"${missing_optional[@]}"}; do
  $SUDO apt-get install -y -qq --no-install-recommends "$p" >/dev/null 2>&1 ||
    echo "setup: optional package $p unavailable (the latency benchmark, the load tests or the browser test will skip)"
done
