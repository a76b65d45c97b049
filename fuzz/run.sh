#!/usr/bin/env bash
# Runs libFuzzer targets, one after the other, each for a fixed time on a scratch copy of its seed
# corpus (fuzz/corpus/<name>/), and prints each one's executions.
# Usage: fuzz/run.sh BUILD_DIR SECONDS [--target NAME]...
#   BUILD_DIR was configured with -DCMAKE_CXX_COMPILER=clang++ -DFEEDLOOP_FUZZ=ON (see
#   fuzz/CMakeLists.txt); the targets are built here if needed. Without --target: all of them.
#   SECONDS is per target.
#   FUZZ_TIMEOUT_S (default 10): libFuzzer's -timeout per input, in wall-clock seconds. Raise it
#   for long runs on a shared machine under nice: a starved process times out on inputs that take
#   milliseconds (check a timeout by running the reproducer alone: BUILD_DIR/fuzz/NAME FILE).
# Exits non-zero on any finding (crash, sanitizer report, failed invariant, timeout, leak, memory
# over 1 GB); the reproducer is left in the work folder that is printed.
set -euo pipefail
usage() {
  echo "usage: $0 BUILD_DIR SECONDS [--target NAME]..." >&2
  exit 2
}
[[ $# -ge 2 ]] || usage
build_dir=$1
seconds=$2
shift 2
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)

# Every target and its corpus folder.
all=(fuzz_gcode_parser fuzz_json_api fuzz_daemon_channels fuzz_mcu_host fuzz_mcu_device
  fuzz_recording_reader fuzz_config_loader fuzz_web_api)
declare -A corpus_of=(
  [fuzz_gcode_parser]=gcode [fuzz_json_api]=json_api [fuzz_daemon_channels]=daemon_channels
  [fuzz_mcu_host]=mcu_host [fuzz_mcu_device]=mcu_device [fuzz_recording_reader]=recording
  [fuzz_config_loader]=config [fuzz_web_api]=web_api)

targets=()
while [[ $# -gt 0 ]]; do
  [[ $1 == --target && $# -ge 2 ]] || usage
  [[ -n ${corpus_of[$2]:-} ]] || { echo "unknown target '$2' (known: ${all[*]})" >&2; exit 2; }
  targets+=("$2")
  shift 2
done
[[ ${#targets[@]} -gt 0 ]] || targets=("${all[@]}")

cmake --build "$build_dir" --target "${targets[@]}" >&2

summary=()
failed=0
for name in "${targets[@]}"; do
  work=$(mktemp -d "${TMPDIR:-/tmp}/${name}.XXXXXX")
  mkdir -p "$work/corpus" "$work/artifacts"
  cp "$here/corpus/${corpus_of[$name]}"/* "$work/corpus/"
  extra=()
  if [[ $name == fuzz_gcode_parser ]]; then
    # Megabyte lines (generated, not kept in the repository): one over the default 256 KiB cap
    # with a valid command after it, one without any newline. The first byte is the mode byte.
    { printf '\000G1 X'; head -c 1100000 /dev/zero | tr '\0' '7'; printf '\nG1 X1\n'; } > "$work/corpus/megabyte_line"
    { printf '\002M117 '; head -c 600000 /dev/zero | tr '\0' '*'; } > "$work/corpus/no_newline"
    extra=(-max_len=1200000)
  fi
  echo "== $name: fuzzing for ${seconds}s in $work" >&2
  start=$SECONDS
  set +e
  "$build_dir/fuzz/$name" "$work/corpus" "${extra[@]}" \
    -max_total_time="$seconds" \
    -rss_limit_mb=1024 \
    -timeout="${FUZZ_TIMEOUT_S:-10}" \
    -print_final_stats=1 \
    -artifact_prefix="$work/artifacts/" > "$work/fuzz.log" 2>&1
  rc=$?
  set -e
  took=$((SECONDS - start))
  findings=$(ls "$work/artifacts" | wc -l)
  stat() { grep -E "^stat::$1:" "$work/fuzz.log" | awk '{print $2}' | tail -n 1; }
  runs=$(stat number_of_executed_units)
  rss=$(stat peak_rss_mb)
  cov=$(grep -E '^#[0-9]+' "$work/fuzz.log" | tail -n 1 | grep -oE 'cov: [0-9]+ ft: [0-9]+' || true)
  line="$name: ${runs:-?} runs in ${took} s ($(( ${runs:-0} / (took > 0 ? took : 1) ))/s), ${cov:-cov ?}, corpus $(ls "$work/corpus" | wc -l) files, peak RSS ${rss:-?} MB, findings $findings"
  summary+=("$line")
  if [[ $rc -ne 0 || $findings -ne 0 ]]; then
    failed=1
    { grep -E 'ERROR|runtime error|SUMMARY|what\(\)|Test unit written' "$work/fuzz.log" | head -n 8
      grep -E '^ +#[0-9]+ .* in feedloop::' "$work/fuzz.log" | head -n 8; } | cut -c1-240 >&2 || true
    echo "FINDING in $name (exit code $rc): reproducer and log in $work" >&2
  else
    rm -rf "$work"
  fi
  echo "$line"
done
echo "== fuzz summary (${seconds} s per target)"
printf '%s\n' "${summary[@]}"
exit $failed
