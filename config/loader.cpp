// Entry points of the config library: YAML text or file in, a fully validated MachineConfig or
// every problem out. Reads the sections in dependency order (kinematics before axes, axes before
// anything that names an axis), then the whole-machine checks.
#include <algorithm>  // stable_sort, count
#include <cerrno>   // errno
#include <cstdio>   // snprintf
#include <cstring>  // strerror
#include <fstream>
#include <sstream>

#include "config/config.hpp"
#include "config/enum_names.hpp"
#include "config/file_text.hpp"
#include "config/sections.hpp"
#include "core/utf8.hpp"

namespace feedloop::config {
namespace {

// The first byte that is not UTF-8 (YAML text is Unicode, YAML 1.2 Sect. 5.2); npos when none.
// yaml-cpp does not check: an invalid name or path would reach the status JSON, M115 and the
// recording header, and to_yaml() would write it back changed.
size_t first_invalid_utf8(std::string_view s) {
  size_t bad = 0;
  for (size_t i = 0; i < s.size();) {
    const size_t n = utf8_sequence_length(s, i, &bad);
    if (n == 0) return i;
    i += n;
  }
  return std::string_view::npos;
}

}  // namespace

bool detail::utf8_or_report(std::string_view yaml, Diagnostics& diag) {
  const size_t at = first_invalid_utf8(yaml);
  if (at == std::string_view::npos) return true;
  const size_t line_start =
      yaml.rfind('\n', at) == std::string_view::npos ? 0 : yaml.rfind('\n', at) + 1;
  const int line = 1 + static_cast<int>(std::count(
                           yaml.begin(), yaml.begin() + static_cast<std::ptrdiff_t>(at), '\n'));
  char hex[8];
  std::snprintf(hex, sizeof hex, "0x%02X", static_cast<unsigned>(static_cast<uint8_t>(yaml[at])));
  diag.add(line, static_cast<int>(at - line_start) + 1,
           std::string("the file is not valid UTF-8 (byte ") + hex + "); save it as UTF-8");
  return false;
}

namespace {

constexpr int kSchemaVersion = 1;

void read_document(const YAML::Node& doc, MachineConfig& cfg, Diagnostics& diag) {
  using namespace detail;
  Marks marks;
  marks.root = doc.Mark();
  MapReader root(doc, "", diag, YAML::Mark());
  if (!root.present()) return;  // reported by MapReader
  int version = kSchemaVersion;
  if (root.integer_as("config_version", version, 1, 1000) && version != kSchemaVersion)
    diag.add(root.get("config_version").Mark(),
             "config_version " + std::to_string(version) + " is not supported (this feedloop reads " +
                 std::to_string(kSchemaVersion) + ")");
  root.string("name", cfg.name);
  marks.kinematics = root.key_mark("kinematics");
  const bool kin_ok = root.choice("kinematics", cfg.kinematics, kinematics_names(), Need::required);
  marks.drive = root.key_mark("drive");
  root.choice("drive", cfg.drive, drive_names());
  marks.control = root.key_mark("control");
  marks.feedforward = root.key_mark("feedforward");
  marks.stepgen = root.key_mark("stepgen");
  read_axes(root, cfg, marks, diag, kin_ok);
  if (kin_ok) {
    read_delta(root, cfg, marks, diag);
  } else {
    root.get("delta");  // depends on the kinematics: not checked without it
  }
  read_planner(root, cfg, diag);
  read_extruder(root, cfg, diag);
  read_servo_control(root, cfg, diag);
  read_model(root, cfg, diag);
  read_stepgen_mcus(root, cfg, marks, diag);
  read_simulator(root, cfg, diag);
  read_io(root, cfg, diag);
  read_thermal(root, cfg, diag);
  root.finish();
  diag.resolve_unknown_keys();
  if (kin_ok) check_machine(cfg, marks, diag);
}

// Parses and validates; fills `out` only when there is no problem.
std::vector<Error> load(std::string_view yaml, const std::string& source, MachineConfig* out) {
  Diagnostics diag(source);
  MachineConfig cfg;
  if (!detail::utf8_or_report(yaml, diag)) return diag.errors();
  try {
    const YAML::Node doc = YAML::Load(std::string(yaml));
    if (!doc.IsDefined() || doc.IsNull()) {
      diag.add(1, 1, "the config is empty (expected a mapping with at least kinematics, axes, mcus)");
    } else {
      read_document(doc, cfg, diag);
    }
  } catch (const YAML::ParserException& e) {
    diag.add(e.mark, "YAML syntax error: " + e.msg);
  } catch (const YAML::Exception& e) {
    diag.add(e.mark, "YAML error: " + e.msg);
  } catch (const std::exception& e) {
    diag.add(0, 0, std::string("internal error while reading the config: ") + e.what());
  }
  if (diag.empty() && out != nullptr) *out = std::move(cfg);
  std::vector<Error> errors = diag.errors();
  std::stable_sort(errors.begin(), errors.end(), [](const Error& a, const Error& b) {
    return std::pair(a.where.line, a.where.column) < std::pair(b.where.line, b.where.column);
  });
  return errors;
}

}  // namespace

std::vector<Error> check_config_text(std::string_view yaml, const std::string& source_name) {
  return load(yaml, source_name, nullptr);
}

Result<MachineConfig> load_config_text(std::string_view yaml, const std::string& source_name) {
  MachineConfig cfg;
  std::vector<Error> errors = load(yaml, source_name, &cfg);
  if (errors.empty()) return cfg;
  Diagnostics all(source_name);
  for (Error& e : errors) all.add(e.where.line, e.where.column, std::move(e.message));
  return all.combined();
}

Result<MachineConfig> load_config_file(const std::string& path) {
  auto text = read_config_file_text(path, "config file");
  if (!text) return text.error();
  return load_config_text(text.value(), path);
}

}  // namespace feedloop::config
