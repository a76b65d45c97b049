#!/usr/bin/env bash
# Runs the G-code parser fuzz target for a fixed time on a scratch copy of the seed corpus.
# Usage: fuzz/run.sh BUILD_DIR SECONDS
#   BUILD_DIR was configured with -DCMAKE_CXX_COMPILER=clang++ -DFEEDLOOP_FUZZ=ON (see
#   fuzz/CMakeLists.txt); the target is built here if needed.
# Exits non-zero on any finding (crash, sanitizer report, timeout, leak, memory over 512 MB);
# the reproducer is left in the work folder that is printed.
set -euo pipefail
if [[ $# -ne 2 ]]; then
  echo "usage: $0 BUILD_DIR SECONDS" >&2
  exit 2
fi
build_dir=$1
seconds=$2
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
cmake --build "$build_dir" --target fuzz_gcode_parser >&2
target="$build_dir/fuzz/fuzz_gcode_parser"
work=$(mktemp -d "${TMPDIR:-/tmp}/fuzz_gcode.XXXXXX")
mkdir -p "$work/corpus" "$work/artifacts"
cp "$here"/corpus/gcode/* "$work/corpus/"
# Megabyte lines (generated, not kept in the repository): one over the default 256 KiB cap with
# a valid command after it, one without any newline. The first byte is the target's mode byte.
{ printf '\000G1 X'; head -c 1100000 /dev/zero | tr '\0' '7'; printf '\nG1 X1\n'; } > "$work/corpus/megabyte_line"
{ printf '\002M117 '; head -c 600000 /dev/zero | tr '\0' '*'; } > "$work/corpus/no_newline"
echo "fuzzing for ${seconds}s in $work" >&2
set +e
"$target" "$work/corpus" \
  -max_total_time="$seconds" \
  -rss_limit_mb=512 \
  -max_len=1200000 \
  -timeout=10 \
  -print_final_stats=1 \
  -artifact_prefix="$work/artifacts/" 2>&1 | tee "$work/fuzz.log" | grep -v '^#[0-9]*.*\(NEW\|REDUCE\|pulse\)' >&2
rc=${PIPESTATUS[0]}
set -e
findings=$(ls "$work/artifacts" | wc -l)
grep -E '^#[0-9]+' "$work/fuzz.log" | tail -n 1 | cut -c1-110 >&2 || true
grep -E '^stat::' "$work/fuzz.log" >&2 || true
echo "exit code $rc, findings $findings, corpus $(ls "$work/corpus" | wc -l) files; log: $work/fuzz.log" >&2
if [[ $rc -ne 0 || $findings -ne 0 ]]; then
  exit 1
fi
rm -rf "$work"
