// Calibration overlays (calibration.hpp): read and validated with the config's own readers
// (detail::read_gantry_axis), so a key means the same in both files.
#include "config/calibration.hpp"
#include "config/file_text.hpp"

#include <cerrno>   // errno
#include <cstring>  // strerror
#include <fstream>
#include <sstream>

#include <yaml-cpp/yaml.h>

#include "config/diagnostics.hpp"
#include "config/map_reader.hpp"
#include "config/sections.hpp"

namespace feedloop::config {
namespace {

constexpr int kCalibrationVersion = 1;

// The keys an overlay may change, for the list of changes (the stepper's are the LPV model's).
struct NumericKey {
  const char* name;
  double (*get)(const GantryModelConfig&);
};
constexpr NumericKey kKeys[] = {
    {"m1_kg", [](const GantryModelConfig& g) { return g.m1_kg; }},
    {"m2_kg", [](const GantryModelConfig& g) { return g.m2_kg; }},
    {"k1_n_per_m", [](const GantryModelConfig& g) { return g.k1_n_per_m; }},
    {"k2_n_per_m", [](const GantryModelConfig& g) { return g.k2_n_per_m; }},
    {"c1_ns_per_m", [](const GantryModelConfig& g) { return g.c1_ns_per_m; }},
    {"c2_ns_per_m", [](const GantryModelConfig& g) { return g.c2_ns_per_m; }},
    {"coulomb_friction_n", [](const GantryModelConfig& g) { return g.coulomb_friction_n; }},
    {"friction_bristle_mm", [](const GantryModelConfig& g) { return g.friction_bristle_mm; }},
    {"backlash_mm", [](const GantryModelConfig& g) { return g.backlash_mm; }},
    {"belt_direction_ratio", [](const GantryModelConfig& g) { return g.belt_direction_ratio; }},
    {"belt_compliance_slope_per_m",
     [](const GantryModelConfig& g) { return g.belt_compliance_slope_per_m; }},
    {"belt_stiffness_reference_mm",
     [](const GantryModelConfig& g) { return g.belt_stiffness_reference_mm; }},
    {"runout_period_mm", [](const GantryModelConfig& g) { return g.runout_period_mm; }},
    {"runout_sin_um", [](const GantryModelConfig& g) { return g.runout_sin_um; }},
    {"runout_cos_um", [](const GantryModelConfig& g) { return g.runout_cos_um; }},
    {"runout_reference_mm", [](const GantryModelConfig& g) { return g.runout_reference_mm; }},
    {"travel_scale", [](const GantryModelConfig& g) { return g.travel_scale; }},
    {"extra_resonance_hz", [](const GantryModelConfig& g) { return g.extra_resonance_hz; }},
    {"extra_resonance_damping",
     [](const GantryModelConfig& g) { return g.extra_resonance_damping; }},
    {"extra_resonance_mass_kg",
     [](const GantryModelConfig& g) { return g.extra_resonance_mass_kg; }},
    {"encoder_delay_ms", [](const GantryModelConfig& g) { return g.encoder_delay_ms; }},
    {"field_lag_ms", [](const GantryModelConfig& g) { return g.field_lag_ms; }},
    {"stepper.belt_unit_stiffness_n",
     [](const GantryModelConfig& g) { return g.stepper.belt_unit_stiffness_n; }},
    {"stepper.pulley_distance_mm",
     [](const GantryModelConfig& g) { return g.stepper.pulley_distance_mm; }},
};

void note_changes(const GantryModelConfig* before, const GantryModelConfig& after, std::vector<std::string>& out) {
  for (const NumericKey& k : kKeys) {
    const double b = before != nullptr ? k.get(*before) : 0.0;
    const double a = k.get(after);
    if (before != nullptr && a == b) continue;
    out.push_back("model.gantry." + after.axis + "." + k.name + ": " + (before ? format_number(b) : "(none)") +
                  " -> " + format_number(a));
  }
}

void read_effects(MapReader& root, const MachineConfig& cfg, std::vector<CalibrationEffect>& out, Diagnostics& diag) {
  const YAML::Node list = root.get("effects");
  if (!list.IsDefined() || list.IsNull()) return;
  if (!list.IsSequence()) {
    diag.add(list.Mark(), "effects: expected a list, got " + node_kind(list));
    return;
  }
  for (std::size_t i = 0; i < list.size(); ++i) {
    const YAML::Node item = list[i];
    MapReader m(item, "effects[" + std::to_string(i) + "]", diag, item.Mark());
    CalibrationEffect e;
    if (m.string("axis", e.axis, Need::required) && cfg.axis(e.axis) == nullptr)
      diag.add(m.key_mark("axis"), m.path() + ": '" + e.axis + "' is not an axis of the config");
    m.string("name", e.name, Need::required);
    MapReader p = m.sub("params");
    for (const std::string& key : p.keys()) {
      double v = 0.0;
      if (p.number(key, v, Range::any())) e.params[key] = v;
    }
    p.finish();
    m.boolean("in_model", e.in_model);
    m.finish();
    out.push_back(std::move(e));
  }
}

// The entry of `list` for v.axis becomes v (appended when there is none).
template <class PerAxis>
void set_for_axis(std::vector<PerAxis>& list, const PerAxis& v) {
  for (PerAxis& existing : list)
    if (existing.axis == v.axis) {
      existing = v;
      return;
    }
  list.push_back(v);
}

// control.axes.<axis>: {kp, ki_per_s}, over the config's gains for that axis.
void read_gains(MapReader& root, const MachineConfig& base, AppliedCalibration& out,
                Diagnostics& diag) {
  if (!root.has("control")) return;
  MapReader control = root.sub("control");
  MapReader axes = control.sub("axes");
  for (const std::string& name : axes.keys()) {
    const YAML::Mark where = axes.key_mark(name);
    MapReader a(axes.get(name), axes.key_path(name), diag, where);
    if (base.axis(name) == nullptr) {
      diag.add(where, axes.key_path(name) + ": '" + name + "' is not an axis of the config");
      continue;
    }
    const AxisGainsConfig before = out.config.control.gains_for(name);
    AxisGainsConfig g = before;
    a.number("kp", g.kp, Range::non_negative());
    a.number("ki_per_s", g.ki_per_s, Range::non_negative());
    a.finish();
    if (g.kp != before.kp)
      out.changes.push_back("control.axes." + name + ".kp: " + format_number(before.kp) + " -> " +
                            format_number(g.kp));
    if (g.ki_per_s != before.ki_per_s)
      out.changes.push_back("control.axes." + name + ".ki_per_s: " +
                            format_number(before.ki_per_s) + " -> " + format_number(g.ki_per_s));
    set_for_axis(out.config.control.axes, g);
    out.gains.push_back(g);
  }
  axes.finish();
  control.finish();
}

void read_overlay(const YAML::Node& doc, const MachineConfig& base, AppliedCalibration& out, Diagnostics& diag) {
  MapReader root(doc, "", diag, YAML::Mark());
  if (!root.present()) return;  // reported by MapReader
  int version = 0;
  if (root.integer_as("calibration_version", version, 1, 1000, Need::required) && version != kCalibrationVersion)
    diag.add(root.get("calibration_version").Mark(),
             "calibration_version " + std::to_string(version) + " is not supported (this feedloop reads " +
                 std::to_string(kCalibrationVersion) + ")");
  root.string("source", out.source);
  MapReader model = root.sub("model");
  MapReader gantry = model.sub("gantry");
  for (const std::string& name : gantry.keys()) {
    const YAML::Mark where = gantry.key_mark(name);
    MapReader g(gantry.get(name), gantry.key_path(name), diag, where);
    if (!detail::gantry_axis_known(base, name, where, diag)) continue;
    const GantryModelConfig* before = base.model.gantry_for(name);
    GantryModelConfig m = before != nullptr ? *before : GantryModelConfig{};
    m.axis = name;
    // Only what the overlay names changes; without the config's entry all six are needed.
    detail::read_gantry_axis(g, m, before != nullptr ? Need::optional : Need::required, diag);
    g.finish();
    note_changes(before, m, out.changes);
    out.axes.push_back(name);
    set_for_axis(out.config.model.gantry, m);
  }
  gantry.finish();
  model.finish();
  read_gains(root, base, out, diag);
  read_effects(root, base, out.effects, diag);
  root.finish();
  diag.resolve_unknown_keys();
}

}  // namespace

Result<AppliedCalibration> apply_calibration_text(const MachineConfig& base, std::string_view yaml,
                                                  const std::string& source_name) {
  Diagnostics diag(source_name);
  AppliedCalibration out;
  out.config = base;
  if (!detail::utf8_or_report(yaml, diag)) return diag.combined();
  try {
    const YAML::Node doc = YAML::Load(std::string(yaml));
    if (!doc.IsDefined() || doc.IsNull())
      diag.add(1, 1, "the calibration file is empty (expected calibration_version and model.gantry)");
    else
      read_overlay(doc, base, out, diag);
  } catch (const YAML::Exception& e) {
    diag.add(e.mark, "YAML syntax error: " + e.msg);
  } catch (const std::exception& e) {
    diag.add(0, 0, std::string("internal error while reading the calibration: ") + e.what());
  }
  if (!diag.empty()) return diag.combined();
  return out;
}

Result<AppliedCalibration> apply_calibration_file(const MachineConfig& base, const std::string& path) {
  auto text = read_config_file_text(path, "calibration file");
  if (!text) return text.error();
  return apply_calibration_text(base, text.value(), path);
}

std::string calibration_yaml(const Calibration& c) {
  YAML::Emitter y;
  y << YAML::BeginMap;
  y << YAML::Key << "calibration_version" << YAML::Value << kCalibrationVersion;
  y << YAML::Key << "source" << YAML::Value << YAML::DoubleQuoted << c.source;
  y << YAML::Key << "model" << YAML::Value << YAML::BeginMap << YAML::Key << "gantry" << YAML::Value << YAML::BeginMap;
  for (const GantryModelConfig& g : c.gantry) {
    y << YAML::Key << g.axis << YAML::Value << YAML::BeginMap;
    for (const NumericKey& k : kKeys) {
      if (std::string_view(k.name).starts_with("stepper.")) continue;
      y << YAML::Key << k.name << YAML::Value << format_number(k.get(g));
    }
    y << YAML::Key << "stepper" << YAML::Value << YAML::BeginMap;
    y << YAML::Key << "belt_unit_stiffness_n" << YAML::Value << format_number(g.stepper.belt_unit_stiffness_n);
    y << YAML::Key << "pulley_distance_mm" << YAML::Value << format_number(g.stepper.pulley_distance_mm);
    y << YAML::EndMap << YAML::EndMap;
  }
  y << YAML::EndMap << YAML::EndMap;
  if (!c.gains.empty()) {
    y << YAML::Key << "control" << YAML::Value << YAML::BeginMap << YAML::Key << "axes"
      << YAML::Value << YAML::BeginMap;
    for (const AxisGainsConfig& g : c.gains) {
      y << YAML::Key << g.axis << YAML::Value << YAML::Flow << YAML::BeginMap;
      y << YAML::Key << "kp" << YAML::Value << format_number(g.kp);
      y << YAML::Key << "ki_per_s" << YAML::Value << format_number(g.ki_per_s);
      y << YAML::EndMap;
    }
    y << YAML::EndMap << YAML::EndMap;
  }
  y << YAML::Key << "effects" << YAML::Value << YAML::BeginSeq;
  for (const CalibrationEffect& e : c.effects) {
    y << YAML::Flow << YAML::BeginMap;
    y << YAML::Key << "axis" << YAML::Value << e.axis << YAML::Key << "name" << YAML::Value << e.name;
    y << YAML::Key << "params" << YAML::Value << YAML::Flow << YAML::BeginMap;
    for (const auto& [k, v] : e.params) y << YAML::Key << k << YAML::Value << format_number(v);
    y << YAML::EndMap;
    y << YAML::Key << "in_model" << YAML::Value << (e.in_model ? "true" : "false");
    y << YAML::EndMap;
  }
  y << YAML::EndSeq << YAML::EndMap;
  return std::string(y.c_str()) + "\n";
}

}  // namespace feedloop::config
