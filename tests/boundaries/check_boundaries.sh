#!/usr/bin/env bash
# Module boundaries (DESIGN.md "Data flow"; issue 13 item 5), checked on the source tree:
#   - control/ takes its own parameter structs: no file in control/ includes config/;
#   - ident/ builds on model/: no file in ident/ includes sim/ or names a sim:: type;
#   - engine/ reaches the plant simulator only through the simulated transport's factory: no file
#     in engine/ includes sim/ except engine/simulated_printer.cpp, and no file but
#     engine/simulated_printer.{hpp,cpp} names a sim:: type in code (comments may).
# Usage: tests/boundaries/check_boundaries.sh [REPOSITORY]   (default: this script's repository)
# Exit 1 listing every violation as file:line: reason: text; 2 on a usage error.
set -euo pipefail
root="${1:-$(cd "$(dirname "$0")/../.." && pwd)}"
cd "$root" || exit 2
for d in control ident engine; do
  [ -d "$d" ] || { echo "check_boundaries: no $d/ in $root" >&2; exit 2; }
done
factory="engine/simulated_printer.cpp"
factory_header="engine/simulated_printer.hpp"

violations=()
# report REASON: reads grep -n output (file:line:text) on stdin.
report() {
  local reason="$1" line
  while IFS= read -r line; do
    violations+=("${line%%:*}:$(cut -d: -f2 <<<"$line"): $reason: $(cut -d: -f3- <<<"$line" | sed 's/^[[:space:]]*//')")
  done
}
sources() { find "$@" -type f \( -name '*.hpp' -o -name '*.h' -o -name '*.cpp' -o -name '*.cc' -o -name '*.ipp' \) | sort; }
# grep -n over files (one name per line on stdin), with the file name even for a single file.
grep_files() { xargs -r -d '\n' grep -nHE "$1" -- || true; }
include_of() { echo "^[[:space:]]*#[[:space:]]*include[[:space:]]*[\"<]$1/"; }
# A sim:: name on a line that is not a // comment.
code_naming_sim() { grep_files '(^|[^A-Za-z0-9_])sim::' | grep -vE '^[^:]+:[0-9]+:[[:space:]]*//' || true; }

report "control/ includes config/ (map the config in engine/control_config)" \
  < <(sources control | grep_files "$(include_of config)")
report "ident/ includes sim/ (simulated experiments belong in sim/experiments)" \
  < <(sources ident | grep_files "$(include_of sim)")
report "ident/ names a sim:: type" < <(sources ident | code_naming_sim)
report "engine/ includes sim/ outside the simulated transport's factory ($factory)" \
  < <(sources engine | grep -vxF "$factory" | grep_files "$(include_of sim)")
report "engine/ names a sim:: type outside the factory (use SimulatedPlant)" \
  < <(sources engine | grep -vxF -e "$factory" -e "$factory_header" | code_naming_sim)
[ -f "$factory" ] || violations+=("$factory: the simulated transport's factory named by this check is missing")

checked=$(sources control ident engine | wc -l)
if [ "${#violations[@]}" -gt 0 ]; then
  echo "module boundaries: ${#violations[@]} violation(s) in $checked files:"
  printf '  %s\n' "${violations[@]}"
  exit 1
fi
echo "module boundaries: $checked files of control/, ident/, engine/ checked, no violation"
