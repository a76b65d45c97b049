#!/usr/bin/env bash
# The boundary check must fail when a boundary is crossed: builds a small tree with one violation
# of each kind (and lines it must accept), runs check_boundaries.sh on it and expects exactly the
# violations planted. Usage: tests/boundaries/check_boundaries_selftest.sh
set -euo pipefail
check="$(cd "$(dirname "$0")" && pwd)/check_boundaries.sh"
t="$(mktemp -d)"
trap 'rm -rf "$t"' EXIT
mkdir -p "$t/control" "$t/ident" "$t/engine"
# Accepted: includes of allowed modules, sim:: in comments, the factory naming and including sim/.
printf '#include "model/lti.hpp"\n// see config/machine_config.hpp\n' >"$t/control/ok.hpp"
printf '#include "ident/trace.hpp"\n  // recorded on sim::GantryAxis\n' >"$t/ident/ok.cpp"
printf '#include "sim/gantry_axis.hpp"\nsim::GantryAxis* g;\n' >"$t/engine/simulated_printer.cpp"
printf 'sim::GantryAxis* simulated_gantry(int joint);\n' >"$t/engine/simulated_printer.hpp"
# Violations: 5 lines.
printf '#include "control/pi_controller.hpp"\n#include "config/machine_config.hpp"\n' >"$t/control/bad.hpp"
printf '#include <sim/rng.hpp>\nvoid f(const sim::Rng& r);\n' >"$t/ident/bad.cpp"
printf '  #  include "sim/delta_plant.hpp"\nstatic feedloop::sim::DeltaPlant* d;  // the plant\n' >"$t/engine/bad.cpp"

set +e
out="$(bash "$check" "$t" 2>&1)"
rc=$?
set -e
echo "$out"
[ "$rc" -eq 1 ] || { echo "selftest: expected exit 1 from the check, got $rc"; exit 1; }
for e in control/bad.hpp:2: ident/bad.cpp:1: ident/bad.cpp:2: engine/bad.cpp:1: engine/bad.cpp:2:; do
  grep -qF "  $e" <<<"$out" || { echo "selftest: violation $e not reported"; exit 1; }
done
grep -q '^module boundaries: 5 violation(s) in 7 files:$' <<<"$out" ||
  { echo "selftest: expected exactly 5 violations in 7 files (an accepted line flagged?)"; exit 1; }
echo "selftest: the check reports the 5 planted violations and nothing else"
