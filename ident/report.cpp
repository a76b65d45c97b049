// Identification report writers (see report.hpp).
#include "ident/report.hpp"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>

namespace feedloop::ident {
namespace {

std::string num(double v, const char* fmt = "%.6g") {
  if (!std::isfinite(v)) return "null";
  char buf[64];
  std::snprintf(buf, sizeof buf, fmt, v);
  return buf;
}

std::string json_escape(const std::string& s) {
  std::string o;
  for (char c : s) {
    if (c == '"' || c == '\\') {
      o += '\\';
      o += c;
    } else if (static_cast<unsigned char>(c) < 0x20) {
      o += ' ';
    } else {
      o += c;
    }
  }
  return o;
}

Status write_file(const std::filesystem::path& p, const std::string& text) {
  std::ofstream f(p, std::ios::binary);
  if (!f) return Error{"cannot write file", SourceLocation{p.string(), 0, 0}};
  f << text;
  if (!f) return Error{"write failed", SourceLocation{p.string(), 0, 0}};
  return Status::Ok();
}

}  // namespace

std::vector<std::pair<std::string, double>> effect_params_report(const AxisModel& m, Effect e) {
  switch (e) {
    case Effect::kPeriodicPosition: return {{"period_mm", m.period_mm}, {"amplitude_um", m.periodic_amplitude_um()}};
    case Effect::kCoulombFriction: return {{"force_n", m.friction_force_n}};
    case Effect::kBacklash: return {{"width_um", m.backlash_width_um}};
    case Effect::kDirectionStiffness: return {{"ratio", m.stiffness_ratio}};
    case Effect::kExtraResonance: return {{"freq_hz", m.extra_freq_hz}, {"damping", m.extra_damping}};
    case Effect::kTimeDelay: return {{"delay_ms", m.delay_ms}};
    case Effect::kScaleError: return {{"scale", m.scale}};
  }
  return {};
}

std::string baseline_description(const AxisModel& m) {
  double psi[4];
  eq17_coefficients(m, psi);
  return "thesis Eq. 13/17 two-mass 4th-order, static gain 1: m1=" + num(m.m1_kg) + " kg m2=" + num(m.m2_kg) +
         " kg (fixed) k1=" + num(m.k1_n_m) + " N/m k2=" + num(m.k2_n_m) + " N/m c1=" + num(m.c1_n_s_m) +
         " N s/m c2=" + num(m.c2_n_s_m) + " N s/m; psi3..psi0=" + num(psi[0]) + "," + num(psi[1]) + "," +
         num(psi[2]) + "," + num(psi[3]);
}

std::string augmented_description(const IdentResult& r) {
  std::string s = baseline_description(r.augmented);
  for (Effect e : r.effects) s += std::string(" + ") + effect_name(e);
  return s;
}

std::string report_json(const IdentResult& r) {
  std::string j = "{\"axis\": \"" + json_escape(r.axis) + "\",\n";
  j += " \"baseline\": {\"model\": \"" + json_escape(baseline_description(r.baseline)) +
       "\", \"rms_um\": " + num(r.baseline_rms_um, "%.4f") + "},\n";
  j += " \"effects\": [";
  for (size_t i = 0; i < r.effects.size(); ++i) {
    if (i > 0) j += ", ";
    j += "{\"name\": \"" + std::string(effect_name(r.effects[i])) + "\", \"params\": {";
    const auto ps = effect_params_report(r.augmented, r.effects[i]);
    for (size_t k = 0; k < ps.size(); ++k) {
      if (k > 0) j += ", ";
      j += "\"" + ps[k].first + "\": " + num(ps[k].second, "%.7g");
    }
    j += "}}";
  }
  j += "],\n";
  j += " \"augmented\": {\"model\": \"" + json_escape(augmented_description(r)) +
       "\", \"rms_um\": " + num(r.augmented_rms_um, "%.4f") + "}}\n";
  return j;
}

std::string report_markdown(const IdentResult& r, const std::string& trace_name) {
  std::string s = "# Identification report: axis " + r.axis + "\n\nTrace: `" + trace_name + "`\n\n";
  s += "## Result\n\n";
  if (r.effects.empty()) {
    s += "Effects found: **none** (the baseline model explains the data).\n\n";
  } else {
    s += "Effects found:\n\n| effect | parameters |\n|---|---|\n";
    for (Effect e : r.effects) {
      std::string ps;
      for (const auto& [k, v] : effect_params_report(r.augmented, e)) ps += k + " = " + num(v) + "  ";
      s += std::string("| ") + effect_name(e) + " | " + ps + "|\n";
    }
    s += "\n";
  }
  s += "| model | RMS residual, whole trace (um) | RMS residual, held-out part (um) |\n|---|---|---|\n";
  s += "| baseline | " + num(r.baseline_rms_um, "%.3f") + " | " + num(r.baseline_validation_rms_um, "%.3f") + " |\n";
  s += "| augmented | " + num(r.augmented_rms_um, "%.3f") + " | " + num(r.augmented_validation_rms_um, "%.3f") +
       " |\n\n";
  s += "## Baseline model\n\n" + baseline_description(r.baseline) + "\n\n";
  s += "## Evidence: every candidate tried\n\nEach round fits every effect not yet in the model (its own "
       "parameters, from an initial guess read off the residual) and compares the RMS on the held-out "
       "part of the trace; the best is kept, refitted with all parameters free, if it lowers the "
       "held-out RMS significantly.\n\n| round | candidate | held-out RMS (um) | kept |\n|---|---|---|---|\n";
  for (const auto& c : r.candidates)
    s += "| " + std::to_string(c.round) + " | " + effect_name(c.effect) + " | " + num(c.validation_rms_um, "%.3f") + " | " +
         (c.kept ? "yes" : "") + " |\n";
  s += "\n`residual.csv` holds the residual (measured - model) before and after, per sample.\n";
  return s;
}

Status write_report(const std::string& dir, const IdentResult& r, const std::vector<double>& time_s,
                    const std::string& trace_name) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) return Error{"cannot create directory: " + ec.message(), SourceLocation{dir, 0, 0}};
  const std::filesystem::path d(dir);
  if (auto s = write_file(d / "report.json", report_json(r)); !s) return s;
  if (auto s = write_file(d / "report.md", report_markdown(r, trace_name)); !s) return s;
  std::string csv = "time_s,residual_before_um,residual_after_um\n";
  char buf[96];
  for (size_t k = 0; k < time_s.size() && k < r.baseline_residual_mm.size() && k < r.augmented_residual_mm.size(); ++k) {
    std::snprintf(buf, sizeof buf, "%.6f,%.4f,%.4f\n", time_s[k], r.baseline_residual_mm[k] * 1e3,
                  r.augmented_residual_mm[k] * 1e3);
    csv += buf;
  }
  return write_file(d / "residual.csv", csv);
}

}  // namespace feedloop::ident
