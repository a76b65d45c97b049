// `feedloop model frf --config FILE --pos X,Y,Z --out FILE.csv [--virtual-work]`: the delta LPV
// model's predicted FRFs (Eq. 29) at one position, written in the DESIGN.md predicted-FRF CSV
// contract (2-125 Hz in 0.5 Hz steps). The config's model.delta_lpv section gives the parameters
// (Table I when the config has none, or without --config); its force_transform (paper Eq. 25/69 by
// default) is overridden by --virtual-work.
#pragma once

#include <string>
#include <vector>

#include "config/machine_config.hpp"
#include "model/delta_params.hpp"

namespace feedloop::cli {

int model_command(const std::vector<std::string>& args);

}  // namespace feedloop::cli
