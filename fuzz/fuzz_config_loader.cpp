// libFuzzer target for the config loader: the input bytes are a YAML printer config as a user
// would write it. Besides memory errors (ASan), UB (UBSan) and escaping exceptions, these trap:
// - load_config_text() and check_config_text() disagree on whether the text is valid;
// - a problem without a location inside the text (line 1..lines+1, column >= 1, the file name);
// - a config that loads but does not survive to_yaml() -> load_config_text() unchanged.
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

#include "config/config.hpp"

namespace {

using namespace feedloop;

void check(bool ok) {
  if (!ok) __builtin_trap();
}

void check_located(const Error& e, int lines) {
  check(e.where.source == "fuzz.yaml");
  check(e.where.line >= 1 && e.where.line <= lines + 1);
  check(e.where.column >= 1);
  check(!e.message.empty());
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  int lines = 1;
  for (char c : text) lines += c == '\n';

  const std::vector<Error> problems = config::check_config_text(text, "fuzz.yaml");
  for (const Error& e : problems) check_located(e, lines);
  const Result<config::MachineConfig> cfg = config::load_config_text(text, "fuzz.yaml");
  check(cfg.ok() == problems.empty());
  if (!cfg) {
    check_located(cfg.error(), lines);
    return 0;
  }
  // Written back, the config loads to the same values (config.hpp: to_yaml's contract).
  const std::string again = config::to_yaml(*cfg);
  const Result<config::MachineConfig> reloaded = config::load_config_text(again, "fuzz.yaml");
  check(reloaded.ok());
  check(*reloaded == *cfg);
  return 0;
}
