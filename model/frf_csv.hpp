// The predicted-FRF CSV contract of DESIGN.md: a header `freq_hz,A_A_re,A_A_im,A_B_re,...,C_C_im`
// (i_j for output carriage i and input carriage j, row-major over i then j), then one row per
// frequency; by default 2 to 125 Hz in 0.5 Hz steps (247 rows). Checked by
// `../shared/tools/check_contracts.py frf FILE`.
#pragma once

#include <string>

#include <Eigen/Dense>

#include "core/result.hpp"
#include "model/delta_lpv.hpp"
#include "model/frequency_grid.hpp"
#include "model/frf_set.hpp"

namespace feedloop::model {

// Writes a set (any grid). Error if the file cannot be written or a value is not finite.
Status write_frf_csv(const std::string& path, const FrfSet& set);

// Eq. 29 of `model` at `pos_mm` on `grid`, written as above (what `feedloop model frf` does).
Status write_frf_csv(const std::string& path, const DeltaLpvModel& model, const Eigen::Vector3d& pos_mm,
                     const FrequencyGrid& grid = {});

// Reads the format back (columns may come in any order; extra columns are ignored; lines
// beginning with '#' are skipped). Errors carry the file, line and column.
Result<FrfSet> read_frf_csv(const std::string& path);

}  // namespace feedloop::model
