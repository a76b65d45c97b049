// `feedloop ident ...`: system identification from traces (docs/ident.md).
//   feedloop ident fit --trace FILE.csv --out DIR [--axis NAME] [--no-plots]
//       fit the baseline model, search the effect vocabulary, write DIR/report.json (DESIGN.md
//       contract), DIR/report.md, the data files (residual.csv, frf.csv, ...) and, with gnuplot,
//       the plots (ident/report.hpp); progress on stderr.
//   feedloop ident frf --trace FILE.csv --out FRF.csv [--axis NAME] [--segment S] [--overlap F] [--window hann|rect]
//       H1 estimate and coherence of the measured against the commanded position (ident/frf.hpp).
//   feedloop ident excite --axis x|y --out FILE.csv [--effect NAME[:key=value,...]]... [--duration S]
//       [--travel MM] [--seed N] [--sweep]
//       record an excitation (random small moves, thesis Appendix D.3, or a sine sweep) on the
//       simulated thesis X or Y axis, with optional effects, as trace CSV v1 (a test-data helper).
#pragma once

#include <string>
#include <vector>

namespace feedloop::cli {

int ident_command(const std::vector<std::string>& args);

}  // namespace feedloop::cli
