// The identification report: DIR/report.json exactly per the DESIGN.md contract
//   {"axis": "x", "baseline": {"model": "...", "rms_um": 12.3},
//    "effects": [{"name": "periodic_position", "params": {"period_mm": 33.9, "amplitude_um": 25.0}}],
//    "augmented": {"model": "...", "rms_um": 3.1}}
// and a human-readable DIR/report.md (fitted parameters, Eq. 17 coefficients, the candidates
// tried each round with their held-out RMS, before/after, the measured FRF against the models,
// the list of plots), plus the data behind it:
//   residual.csv          time_s,residual_before_um,residual_after_um,cmd_mm (per sample)
//   frf.csv               H1 of the trace (meas against cmd) on the 2-125 Hz grid with coherence,
//                         and the baseline and augmented models' FRF (ident/frf.hpp)
//   residual_psd.csv      Welch PSD of the residual before and after
//   evidence_<effect>.csv per effect found: the residual of the model without that effect and
//                         what the effect accounts for, against position or time
// and, when gnuplot is present (ident/plots.hpp), bode.png, residual_time.png,
// residual_position.png, residual_psd.png and evidence_<effect>.png.
#pragma once

#include <string>
#include <vector>

#include "core/result.hpp"
#include "ident/fit.hpp"

namespace feedloop::ident {

// (name, value) pairs of an effect's parameters in the vocabulary's units.
std::vector<std::pair<std::string, double>> effect_params_report(const AxisModel& m, Effect e);

// One-line model descriptions for report.json.
std::string baseline_description(const AxisModel& m);
std::string augmented_description(const IdentResult& r);

std::string report_json(const IdentResult& r);

// What report.md says beyond the fit: the FRF comparison and the plots.
struct ReportExtras {
  std::string frf_summary;               // markdown paragraph(s); "" when no FRF
  std::vector<std::string> plots;        // image files drawn
  std::vector<std::string> plot_titles;
  std::string plot_note;                 // why plots are missing, "" when none are
};
std::string report_markdown(const IdentResult& r, const std::string& trace_name, const ReportExtras& extras = {});

struct ReportOptions {
  bool plots = true;  // false: data files only, no gnuplot
};

// Writes everything listed above into dir (created if missing). cmd_mm/meas_mm are the trace's
// axis that r was fitted on, sampled at period_s. A trace too short or too slowly sampled for
// the FRF, or a missing gnuplot, only leaves a note in report.md.
Status write_report(const std::string& dir, const IdentResult& r, const std::vector<double>& time_s,
                    const std::vector<double>& cmd_mm, const std::vector<double>& meas_mm, double period_s,
                    const std::string& trace_name, const ReportOptions& options = {},
                    ReportExtras* extras_out = nullptr);

}  // namespace feedloop::ident
