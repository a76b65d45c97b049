#!/usr/bin/env bash
# Installs feedloop's build and test dependencies from Debian's packages. Idempotent; run as root
# (or with sudo available). Only Debian's archive is contacted.
set -euo pipefail

PACKAGES=(
  build-essential cmake ninja-build pkg-config git python3
  libeigen3-dev libusb-1.0-0-dev libboost-dev libspdlog-dev libyaml-cpp-dev
  libgtest-dev libgmock-dev libsystemd-dev libfftw3-dev nlohmann-json3-dev
  libsqlite3-dev                      # the web server's database (server.database.*)
  clang libclang-rt-14-dev            # libFuzzer + sanitizer runtimes
  printrun                            # pronsole: the serial host used in the pty test
  systemd                             # systemd-analyze verify of the unit
  socat xz-utils
  gnuplot-nox                         # the identification report's plots (ident fit --out DIR)
)
OPTIONAL=(rt-tests stress-ng          # servo-latency benchmark only
  chromium nodejs npm)                # the browser test (ctest -L browser) only

missing=()
for p in "${PACKAGES[@]}" "${OPTIONAL[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "setup: all dependencies present"
  exit 0
fi
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
echo "setup: installing ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${PACKAGES[@]}" >/dev/null
$SUDO apt-get install -y -qq --no-install-recommends "${OPTIONAL[@]}" >/dev/null || \
  echo "setup: optional packages (${OPTIONAL[*]}) unavailable; the latency benchmark and the browser test will skip"
