// The delta paper's Sect. IV measurements (delta-lpv-receptance-coupling.txt) simulated on
// sim::DeltaPlant, as the input of the identification procedure (ident/delta/delta_ident.hpp,
// which describes each measurement). A simulated experiment: it uses both the plant (sim/) and
// identification's types and H1 estimator (ident/), so it lives above both
// (feedloop_sim_experiments); ident/ itself never reaches into sim/.
#pragma once

#include <complex>
#include <vector>

#include "core/result.hpp"
#include "ident/delta/delta_ident.hpp"
#include "sim/delta_plant.hpp"

namespace feedloop::sim {

// Runs the simulated experiments on plants built from `truth` (positions from plan). Error when a
// plant cannot be built (bad parameters, unreachable position) or a grid is invalid.
Result<ident::delta::DeltaMeasurements> simulate_measurements(
    const DeltaPlantParams& truth, const ident::delta::MeasurementPlan& plan);

// The Sect. IV-A carriage experiment in the time domain instead: a random-phase multisine with a
// line at every carriage_grid frequency (period 1 / grid step) commanded to carriage A through
// step pulses (one update per simulator substep, so each step lands on an update instant), the
// true carriage position sampled at the same rate, H1 (ident/frf.hpp: rectangular window,
// one period per segment, no overlap, the first period discarded) divided by the zero-order hold
// of the step staircase, (1 - e^{-jwT}) / (jwT). added_mass: with plan.m_add_kg on the carriage.
struct SweepSpec {
  double rms_mm = 0.05;  // of the commanded multisine
  int periods = 8;       // averaged (one more is run first to settle)
};
Result<std::vector<std::complex<double>>> measure_carriage_h1(
    const DeltaPlantParams& truth, const ident::delta::MeasurementPlan& plan, bool added_mass,
    const SweepSpec& sweep = {});

}  // namespace feedloop::sim
