// `feedloop calibrate`: calibrates a running feedloopd's machine from its own data (issue 15,
// docs/calibration.md). Over the daemon's JSON API:
//   1. a check pattern (a circle and a small star at 90 mm/s in the bed's middle) as a print job:
//      the tracking error e_t before;
//   2. per axis, the calibration program (calibration/excitation_gcode.hpp) as a print job; the
//      daemon records it like any print, and its recording is the trace (recorder/trace_export);
//   3. the identification of each axis (ident::identify_axis: baseline, effects, held-out RMS),
//      its report and plots in OUT/<axis>/;
//   4. the calibration overlay OUT/calibration.yaml, installed where the daemon reads it (its
//      `info.calibration_path`) and loaded (`config.reload`);
//   5. the check pattern again: e_t after; OUT/report.md and OUT/report.json say before and after.
//
//   feedloop calibrate [--axes x,y] [--out DIR] [--api PATH] [--no-install] [--seed N]
//   feedloop calibrate --check-only [--api PATH]   (the check pattern's e_t alone)
//   feedloop calibrate --write-gcode DIR [--config CFG.yaml] [--axes x,y] [--seed N]
//       (only the programs, to run through any host)
#pragma once

#include <string>
#include <vector>

namespace feedloop::cli {

int calibrate_command(const std::vector<std::string>& args);

}  // namespace feedloop::cli
