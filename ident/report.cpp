// Identification report writers (see report.hpp).
#include "ident/report.hpp"

#include "ident/frf.hpp"
#include "ident/plots.hpp"

#include <algorithm>
#include <cmath>
#include <complex>
#include <cstdio>
#include <cstdlib>  // std::strtod
#include <filesystem>
#include <fstream>

#include <nlohmann/json.hpp>

namespace feedloop::ident {
namespace {

std::string num(double v, const char* fmt = "%.6g") {
  if (!std::isfinite(v)) return "null";
  char buf[64];
  std::snprintf(buf, sizeof buf, fmt, v);
  return buf;
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
    case Effect::kCoulombFriction:
      return {{"force_n", m.friction_force_n}, {"presliding_um", m.presliding_um}};
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
         num(psi[2]) + "," + num(psi[3]) +
         (m.field_lag_ms > 0.0 ? "; c1 on the load angle, the field lagging by " + num(m.field_lag_ms) + " ms"
                               : std::string());
}

std::string augmented_description(const IdentResult& r) {
  std::string s = baseline_description(r.augmented);
  for (Effect e : r.effects) s += std::string(" + ") + effect_name(e);
  if (r.drag_in_baseline)
    s += " + the carriage's drag " + num(r.augmented.friction_force_n, "%.3g") +
         " N (Dahl friction below the naming threshold, not an effect found)";
  return s;
}

std::string report_json(const IdentResult& r) {
  // Insertion order kept (DESIGN.md's layout: axis, baseline, effects, ..., augmented); figures as
  // numbers rounded to what they mean, a figure that is not finite as null.
  using nlohmann::ordered_json;
  auto figure = [](double v, int decimals) -> ordered_json {
    if (!std::isfinite(v)) return nullptr;
    const double scale = std::pow(10.0, decimals);
    return std::round(v * scale) / scale;
  };
  auto significant = [](double v) -> ordered_json {
    if (!std::isfinite(v)) return nullptr;
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.7g", v);  // what the fit can tell: 7 significant digits
    return std::strtod(buf, nullptr);
  };
  ordered_json j;
  j["axis"] = r.axis;
  j["baseline"] = {{"model", baseline_description(r.baseline)},
                   {"rms_um", figure(r.baseline_rms_um, 4)}};
  ordered_json effects = ordered_json::array();
  for (Effect e : r.effects) {
    ordered_json params = ordered_json::object();
    for (const auto& [name, value] : effect_params_report(r.augmented, e))
      params[name] = significant(value);
    effects.push_back({{"name", effect_name(e)}, {"params", std::move(params)}});
  }
  j["effects"] = std::move(effects);
  // The carried model's belt along the travel (fit.cpp): its slope (0: uniform) and the held-out
  // RMS of the fit with a slope, kept or not (0: not tried).
  j["belt_along_travel"] = {
      {"compliance_slope_per_m", significant(r.carried.compliance_slope_per_m)},
      {"reference_mm", significant(r.carried.stiffness_reference_mm)},
      {"with_slope_held_out_rms_um", figure(r.slope_validation_rms_um, 4)},
      {"carried_held_out_rms_um", figure(r.carried_validation_rms_um, 4)}};
  // The carried model's motor (fit.cpp): its field lag (0: Eq. 13's motor, damped against the
  // frame) and the held-out RMS of the fit with one, kept or not (0: not tried).
  j["motor_field"] = {{"field_lag_ms", significant(r.carried.field_lag_ms)},
                      {"k1_n_m", significant(r.carried.k1_n_m)},
                      {"c1_n_s_m", significant(r.carried.c1_n_s_m)},
                      {"with_field_lag_held_out_rms_um", figure(r.field_lag_validation_rms_um, 4)},
                      {"eq13_motor_held_out_rms_um", figure(r.eq13_motor_validation_rms_um, 4)}};
  j["augmented"] = {{"model", augmented_description(r)}, {"rms_um", figure(r.augmented_rms_um, 4)}};
  // Model descriptions are built from numbers and fixed words; replace (not throw on) anything
  // that is not UTF-8 all the same.
  return j.dump(1, ' ', false, ordered_json::error_handler_t::replace) + "\n";
}

std::string report_markdown(const IdentResult& r, const std::string& trace_name, const ReportExtras& extras) {
  std::string s = "# Identification report: axis " + r.axis + "\n\nTrace: `" + trace_name + "`\n\n";
  s += "## Result\n\n";
  for (const std::string& w : r.warnings) s += "**Warning:** " + w + ".\n\n";
  if (r.effects.empty()) {
    s += r.warnings.empty() ? "Effects found: **none** (the baseline model explains the data).\n\n"
                            : "Effects found: **none**.\n\n";
  } else {
    s += "Effects found:\n\n| effect | parameters |\n|---|---|\n";
    for (Effect e : r.effects) {
      std::string ps;
      for (const auto& [k, v] : effect_params_report(r.augmented, e)) ps += k + " = " + num(v) + "  ";
      s += std::string("| ") + effect_name(e) + " | " + ps + "|\n";
    }
    s += "\n";
  }
  if (r.drag_in_baseline)
    s += "The model also carries the carriage's own drag, a friction of " +
         num(r.augmented.friction_force_n, "%.3g") + " N (presliding " +
         num(r.augmented.presliding_um, "%.3g") +
         " um): below what `coulomb_friction` names, but the held-out part needed it by the same "
         "margin as an effect (the candidate marked \"carried, unnamed\" below).\n\n";
  s += "| model | RMS residual, whole trace (um) | RMS residual, held-out part (um) |\n|---|---|---|\n";
  s += "| baseline | " + num(r.baseline_rms_um, "%.3f") + " | " + num(r.baseline_validation_rms_um, "%.3f") + " |\n";
  s += "| augmented | " + num(r.augmented_rms_um, "%.3f") + " | " + num(r.augmented_validation_rms_um, "%.3f") +
       " |\n\n";
  s += "## Baseline model\n\n" + baseline_description(r.baseline) + "\n\n";
  if (r.carried.compliance_slope_per_m != 0.0)
    s += "The belt along the travel: 1 / K2(x) = (1 / k2) (1 + s (x - x_ref)), s = " +
         num(r.carried.compliance_slope_per_m, "%.4g") +
         " /m about x_ref = " + num(r.carried.stiffness_reference_mm, "%.2f") +
         " mm (held-out RMS " + num(r.slope_validation_rms_um, "%.3f") + " um with it).\n\n";
  else if (r.slope_validation_rms_um > 0.0)
    s += "The belt along the travel: uniform (with a compliance slope the held-out RMS was " +
         num(r.slope_validation_rms_um, "%.3f") + " um, not lower enough).\n\n";
  if (r.carried.field_lag_ms > 0.0)
    s += "The motor: damped on its load angle, the driver's field lagging the command by " +
         num(r.carried.field_lag_ms, "%.3g") + " ms (k1 = " + num(r.carried.k1_n_m) +
         " N/m, c1 = " + num(r.carried.c1_n_s_m) + " N s/m against the field; held-out RMS " +
         num(r.field_lag_validation_rms_um, "%.3f") + " um with it, " +
         num(r.eq13_motor_validation_rms_um, "%.3f") + " um with Eq. 13's motor).\n\n";
  else if (r.field_lag_validation_rms_um > 0.0)
    s += "The motor: Eq. 13's (with its damping on the load angle and a field lag the held-out RMS "
         "was " +
         num(r.field_lag_validation_rms_um, "%.3f") + " um, not lower enough).\n\n";
  s += "## Evidence: every candidate tried\n\nEach round fits every effect not yet in the model "
       "(its own parameters, from an initial guess read off the residual) and compares the RMS on "
       "the held-out part of the trace; the best is kept, refitted with all parameters free, if it "
       "lowers the held-out RMS significantly. When none does, the best one or two are each taken "
       "as the start of a second screening (rows \"X after Y\"), and a pair is kept when together "
       "they lower it by the margin twice and by the margin over the best single effect. A "
       "resonance \"read off the FRF\" is a mode fitted to the measured frequency response (the "
       "baseline refitted around it), kept when the current model misses the held-out FRF near "
       "its frequency and the mode at least halves that. With two or more kept, each is taken "
       "out in turn and the rest refitted (rows \"without X\"): the one whose absence costs least "
       "is dropped when the rest predict the held-out part within the margin.\n\n"
       "| round | candidate | held-out RMS (um) | kept |\n|---|---|---|---|\n";
  for (const auto& c : r.candidates)
    s += "| " + std::to_string(c.round) + " | " + (c.without ? "without " : "") +
         effect_name(c.effect) +
         (c.with >= 0 ? std::string(" after ") + effect_name(static_cast<Effect>(c.with))
                      : std::string()) +
         (c.from_frf ? " (read off the FRF)" : "") +
         (c.from_band ? " (at the drive's step, where it shows)" : "") + " | " +
         num(c.validation_rms_um, "%.3f") + " | " +
         (c.unnamed   ? "carried, unnamed"
          : c.dropped ? "kept, then dropped"
          : c.kept    ? "yes"
                      : "") +
         " |\n";
  s += "\n## Measured frequency response\n\n";
  s += extras.frf_summary.empty() ? std::string("No FRF estimate.\n") : extras.frf_summary;
  s += "\n## Plots\n\n";
  for (size_t i = 0; i < extras.plots.size(); ++i)
    s += "- [`" + extras.plots[i] + "`](" + extras.plots[i] + "): " +
         (i < extras.plot_titles.size() ? extras.plot_titles[i] : std::string()) + "\n";
  if (!extras.plot_note.empty()) s += "\n**Note:** " + extras.plot_note + ".\n";
  s += "\n## Data files\n\n"
       "- `residual.csv`: time_s, residual (measured - model) before and after in um, commanded "
       "position in mm, per sample\n"
       "- `frf.csv`: measured H1 (magnitude, unwrapped phase in deg, coherence) and the baseline "
       "and augmented "
       "models' FRF from 2 Hz to a fifth of the sampling rate (200 Hz at 1 kHz)\n"
       "- `residual_psd.csv`: power spectral density of the residual before and after (um^2/Hz)\n"
       "- `evidence_<effect>.csv`: per effect found, the residual without it and what it accounts "
       "for\n";
  return s;
}

namespace {

constexpr double kPi = 3.14159265358979323846;

// Phase in degrees, unwrapped along the grid (jumps of more than 180 deg between neighbours are
// taken as wraps).
std::vector<double> unwrapped_phase_deg(const std::vector<std::complex<double>>& h) {
  std::vector<double> out(h.size(), 0.0);
  double offset = 0.0, prev = 0.0;
  for (size_t i = 0; i < h.size(); ++i) {
    double p = std::arg(h[i]) * 180.0 / kPi;
    if (i > 0) {
      while (p + offset - prev > 180.0) offset -= 360.0;
      while (p + offset - prev < -180.0) offset += 360.0;
    }
    out[i] = p + offset;
    prev = out[i];
  }
  return out;
}

// Mean |error| of a model FRF against H1 where coherence > 0.9: magnitude (relative) and phase (deg).
void frf_error(const FrfEstimate& e, const std::vector<std::complex<double>>& m, double* mag_pct, double* phase_deg,
               int* points) {
  double sm = 0.0, sp = 0.0;
  int n = 0;
  for (size_t i = 0; i < e.h1.size() && i < m.size(); ++i) {
    if (!(e.coherence[i] > 0.9)) continue;
    sm += std::abs(std::abs(e.h1[i]) / std::abs(m[i]) - 1.0);
    sp += std::abs(std::arg(e.h1[i] / m[i])) * 180.0 / kPi;
    ++n;
  }
  *points = n;
  *mag_pct = n > 0 ? 100.0 * sm / n : 0.0;
  *phase_deg = n > 0 ? sp / n : 0.0;
}

bool position_coordinate(Effect e) { return e == Effect::kPeriodicPosition || e == Effect::kScaleError; }

}  // namespace

Status write_report(const std::string& dir, const IdentResult& r, const std::vector<double>& time_s,
                    const std::vector<double>& cmd_mm, const std::vector<double>& meas_mm, double period_s,
                    const std::string& trace_name, const ReportOptions& options, ReportExtras* extras_out) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) return Error{"cannot create directory: " + ec.message(), SourceLocation{dir, 0, 0}};
  const std::filesystem::path d(dir);
  const std::filesystem::path da = std::filesystem::absolute(d, ec);
  const auto q = [&](const std::string& file) { return gnuplot_quote((da / file).string()); };
  if (auto s = write_file(d / "report.json", report_json(r)); !s) return s;
  const size_t n = std::min({time_s.size(), r.baseline_residual_mm.size(), r.augmented_residual_mm.size(),
                             cmd_mm.size(), meas_mm.size()});
  char buf[160];
  {
    std::string csv = "time_s,residual_before_um,residual_after_um,cmd_mm\n";
    csv.reserve(n * 40);
    for (size_t k = 0; k < n; ++k) {
      std::snprintf(buf, sizeof buf, "%.6f,%.4f,%.4f,%.6f\n", time_s[k], r.baseline_residual_mm[k] * 1e3,
                    r.augmented_residual_mm[k] * 1e3, cmd_mm[k]);
      csv += buf;
    }
    if (auto s = write_file(d / "residual.csv", csv); !s) return s;
  }
  ReportExtras extras;
  std::vector<PlotSpec> plots;
  const std::string axis = r.axis;

  // Measured FRF (H1 of meas against cmd) and the models' FRF on the identification's grid (the
  // papers' 0.5 Hz steps from 2 Hz to a fifth of the sampling rate: 200 Hz at 1 kHz, where the
  // identification looks for a mode).
  const model::FrequencyGrid grid = identification_frf_grid(period_s > 0.0 ? period_s : 1e-3);
  char grid_text[64];
  std::snprintf(grid_text, sizeof grid_text, "%g-%g Hz", grid.start_hz, grid.stop_hz);
  const double fs = period_s > 0.0 ? 1.0 / period_s : 0.0;
  auto est = estimate_frf_h1(cmd_mm, meas_mm, fs, grid);
  if (!est) {
    extras.frf_summary = "Not estimated: " + est.error().message + ".\n";
  } else {
    const FrfEstimate& e = est.value();
    auto fb = axis_model_frf(r.baseline, period_s, grid);
    auto fa = axis_model_frf(r.augmented, period_s, grid);
    std::string csv = "freq_hz,h1_mag,h1_phase_deg,coherence,baseline_mag,baseline_phase_deg,augmented_mag,augmented_phase_deg\n";
    const std::vector<double> ph = unwrapped_phase_deg(e.h1);
    const std::vector<double> pb = fb ? unwrapped_phase_deg(fb.value()) : std::vector<double>(e.h1.size(), 0.0);
    const std::vector<double> pa = fa ? unwrapped_phase_deg(fa.value()) : std::vector<double>(e.h1.size(), 0.0);
    for (size_t i = 0; i < e.freq_hz.size(); ++i) {
      std::snprintf(buf, sizeof buf, "%.3f,%.8g,%.4f,%.6f,%.8g,%.4f,%.8g,%.4f\n", e.freq_hz[i], std::abs(e.h1[i]), ph[i],
                    e.coherence[i], fb ? std::abs(fb.value()[i]) : 0.0, pb[i], fa ? std::abs(fa.value()[i]) : 0.0, pa[i]);
      csv += buf;
    }
    if (auto s = write_file(d / "frf.csv", csv); !s) return s;
    int coherent = 0;
    double bm = 0.0, bp = 0.0, am = 0.0, ap = 0.0;
    if (fb) frf_error(e, fb.value(), &bm, &bp, &coherent);
    if (fa) frf_error(e, fa.value(), &am, &ap, &coherent);
    double cmin = 1.0;
    for (double c : e.coherence) cmin = std::min(cmin, c);
    extras.frf_summary =
        "H1 estimate of the measured position against the commanded one (`frf.csv`): Welch "
        "averaging over " +
        std::to_string(e.segments) + " Hann-windowed, linearly detrended segments of " +
        num(e.segment_s) + " s (50 % overlap), on the " + grid_text + " grid in 0.5 Hz steps (" +
        std::to_string(e.freq_hz.size()) + " points). Coherence > 0.9 at " +
        std::to_string(coherent) + " points (lowest " + num(cmin, "%.3f") +
        "). Where coherent, the mean |H1 / G - 1| and phase difference are:\n\n"
        "| model | magnitude (%) | phase (deg) |\n|---|---|---|\n"
        "| baseline | " +
        num(bm, "%.2f") + " | " + num(bp, "%.2f") +
        " |\n"
        "| augmented | " +
        num(am, "%.2f") + " | " + num(ap, "%.2f") +
        " |\n\n"
        "The models' FRF is that of their linear part (the baseline, plus extra_resonance, "
        "time_delay and "
        "scale_error when found), sampled with a first-order hold like the trace; the other "
        "effects are "
        "nonlinear and show in the time domain only. Sparse steps (one per sample) reach the motor "
        "up to "
        "half a sample later than a first-order hold, a few degrees of phase near 50 Hz.\n";
    plots.push_back(PlotSpec{
        "bode",
        "Bode plot: measured H1 (points) against the fitted baseline and augmented models, "
        "with the coherence",
        1000, 950,
        "set multiplot layout 3,1 title 'axis " + axis +
            ": measured H1 vs fitted models'\n"
            "set logscale x\nset xrange [" +
            num(grid.start_hz, "%g") + ":" + num(grid.stop_hz, "%g") +
            "]\nset key bottom left\n"
            "set ylabel 'magnitude (dB)'\n"
            "plot " +
            q("frf.csv") +
            " skip 1 using 1:(20*log10($2)) with points pt 7 ps 0.5 lc rgb '#1f77b4' title "
            "'measured H1', "
            "'' skip 1 using 1:(20*log10($5)) with lines lw 2 lc rgb '#d62728' title 'baseline', "
            "'' skip 1 using 1:(20*log10($7)) with lines lw 2 dt 2 lc rgb '#2ca02c' title "
            "'augmented'\n"
            "set ylabel 'phase (deg)'\n"
            "plot " +
            q("frf.csv") +
            " skip 1 using 1:3 with points pt 7 ps 0.5 lc rgb '#1f77b4' title 'measured H1', "
            "'' skip 1 using 1:6 with lines lw 2 lc rgb '#d62728' title 'baseline', "
            "'' skip 1 using 1:8 with lines lw 2 dt 2 lc rgb '#2ca02c' title 'augmented'\n"
            "set ylabel 'coherence'\nset xlabel 'frequency (Hz)'\nset yrange [0:1.05]\n"
            "plot " +
            q("frf.csv") +
            " skip 1 using 1:4 with linespoints pt 7 ps 0.3 lc rgb '#1f77b4' title 'coherence', "
            "0.9 with lines dt 3 lc rgb 'gray' title '0.9'\n"
            "unset multiplot"});
  }

  // Residual spectrum before and after.
  {
    model::FrequencyGrid pg;
    pg.start_hz = 0.5;
    pg.step_hz = 0.5;
    pg.stop_hz = std::floor(std::min(250.0, 0.5 * fs) / 0.5) * 0.5;
    std::vector<double> rb(n), ra(n);
    for (size_t k = 0; k < n; ++k) {
      rb[k] = r.baseline_residual_mm[k] * 1e3;
      ra[k] = r.augmented_residual_mm[k] * 1e3;
    }
    auto psd = pg.stop_hz >= pg.start_hz ? estimate_frf_h1(rb, ra, fs, pg) : Result<FrfEstimate>(Error{"no grid", {}});
    if (psd) {
      std::string csv = "freq_hz,psd_before_um2_hz,psd_after_um2_hz\n";
      for (size_t i = 0; i < psd.value().freq_hz.size(); ++i) {
        std::snprintf(buf, sizeof buf, "%.3f,%.6g,%.6g\n", psd.value().freq_hz[i], psd.value().input_psd[i],
                      psd.value().output_psd[i]);
        csv += buf;
      }
      if (auto s = write_file(d / "residual_psd.csv", csv); !s) return s;
      plots.push_back(PlotSpec{"residual_psd", "Power spectral density of the residual before and after (time domain)",
                               1000, 600,
          "set title 'axis " + axis + ": residual spectrum'\nset logscale xy\nset autoscale xfix\nset format y '%.0e'\n"
          "set xlabel 'frequency (Hz)'\nset ylabel 'PSD (um^2/Hz)'\n"
          "plot " + q("residual_psd.csv") + " skip 1 using 1:2 with lines lw 1.5 lc rgb '#d62728' title 'before (baseline)', "
          "'' skip 1 using 1:3 with lines lw 1.5 lc rgb '#2ca02c' title 'after (augmented)'"});
    }
  }
  plots.push_back(PlotSpec{"residual_time", "Residual (measured - model) against time, before and after", 1200, 600,
      "set title 'axis " + axis + ": residual, baseline " + num(r.baseline_rms_um, "%.3f") + " um RMS -> augmented " +
      num(r.augmented_rms_um, "%.3f") + " um RMS'\nset xlabel 'time (s)'\nset ylabel 'residual (um)'\n"
      "plot " + q("residual.csv") + " skip 1 using 1:2 with lines lc rgb '#d62728' title 'before (baseline)', "
      "'' skip 1 using 1:3 with lines lc rgb '#2ca02c' title 'after (augmented)'"});
  plots.push_back(PlotSpec{"residual_position", "Residual against commanded position, before and after", 1200, 600,
      "set title 'axis " + axis + ": residual against position'\nset xlabel 'commanded position (mm)'\n"
      "set ylabel 'residual (um)'\n"
      "plot " + q("residual.csv") + " skip 1 using 4:2 with points pt 7 ps 0.15 lc rgb '#d62728' title 'before (baseline)', "
      "'' skip 1 using 4:3 with points pt 7 ps 0.15 lc rgb '#2ca02c' title 'after (augmented)'"});

  // Evidence per effect: the model without it leaves a residual that the effect accounts for.
  std::vector<double> y_aug(n);
  for (size_t k = 0; k < n; ++k) y_aug[k] = meas_mm[k] - r.augmented_residual_mm[k];
  for (Effect e : r.effects) {
    AxisModel without = r.augmented;
    without.set(e, false);
    std::vector<double> y_wo;
    if (!simulate_axis(without, cmd_mm, period_s, &y_wo).ok() || y_wo.size() < n) continue;
    const std::string name = effect_name(e);
    std::string csv;
    std::string xlabel;
    size_t begin = 0, end = n, stride = 1;
    if (position_coordinate(e)) {
      csv = "cmd_mm,residual_without_um,effect_um,residual_after_um\n";
      xlabel = "commanded position (mm)";
      stride = std::max<size_t>(1, n / 20000);
    } else {
      // The 2 s window where the effect accounts for most.
      csv = "time_s,residual_without_um,effect_um,residual_after_um\n";
      xlabel = "time (s)";
      const auto win = std::min(n, static_cast<size_t>(std::max(2.0 / std::max(period_s, 1e-9), 10.0)));
      const size_t hop = std::max<size_t>(1, win / 4);
      double best = -1.0;
      for (size_t b = 0; b + win <= n; b += hop) {
        double ssum = 0.0;
        for (size_t k = b; k < b + win; ++k) ssum += (y_aug[k] - y_wo[k]) * (y_aug[k] - y_wo[k]);
        if (ssum > best) {
          best = ssum;
          begin = b;
        }
      }
      end = begin + win;
    }
    for (size_t k = begin; k < end; k += stride) {
      std::snprintf(buf, sizeof buf, "%.6f,%.4f,%.4f,%.4f\n", position_coordinate(e) ? cmd_mm[k] : time_s[k],
                    (meas_mm[k] - y_wo[k]) * 1e3, (y_aug[k] - y_wo[k]) * 1e3, r.augmented_residual_mm[k] * 1e3);
      csv += buf;
    }
    const std::string file = "evidence_" + name + ".csv";
    if (auto s = write_file(d / file, csv); !s) return s;
    std::string params;
    for (const auto& [k, v] : effect_params_report(r.augmented, e)) params += k + " " + num(v, "%.4g") + " ";
    const std::string style = position_coordinate(e) ? "points pt 7 ps 0.15" : "lines";
    plots.push_back(PlotSpec{"evidence_" + name,
        "Evidence for " + name + ": the residual of the model without it (red) and what the effect accounts for (black)",
        1200, 600,
        "set title 'axis " + axis + ": evidence for " + name + " (" + params + ")'\nset xlabel '" + xlabel + "'\n"
        "set ylabel 'um'\n"
        "plot " + q(file) + " skip 1 using 1:2 with " + style + " lc rgb '#d62728' title 'residual without " + name + "', "
        "'' skip 1 using 1:3 with " + style + " lw 2 lc rgb 'black' title '" + name + " (fitted)', "
        "'' skip 1 using 1:4 with " + style + " lc rgb '#2ca02c' title 'residual after'"});
  }

  if (options.plots) {
    const PlotOutcome po = draw_plots(dir, plots);
    extras.plots = po.drawn;
    extras.plot_titles = po.drawn_titles;
    extras.plot_note = po.note;
  } else {
    extras.plot_note = "plots not drawn (disabled); the data files and gnuplot scripts are not written either";
  }
  if (auto s = write_file(d / "report.md", report_markdown(r, trace_name, extras)); !s) return s;
  if (extras_out != nullptr) *extras_out = extras;
  return Status::Ok();
}

}  // namespace feedloop::ident
