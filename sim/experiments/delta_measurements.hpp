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
  // false: the true carriage position (the check against the small-signal FRF); true: the
  // carriage's linear encoder as the MCU reads it (truth.encoder: its quantisation, noise and
  // sampling delay), the measurement a machine can make.
  bool read_encoders = false;
};
Result<std::vector<std::complex<double>>> measure_carriage_h1(
    const DeltaPlantParams& truth, const ident::delta::MeasurementPlan& plan, bool added_mass,
    const SweepSpec& sweep = {});

// q / q_d of the full assembly with the nozzle at position_mm (at rest there, gravity sag
// included), measured as on a machine: three experiments, each a random-phase multisine with a
// line at every `grid` frequency commanded to one carriage through step pulses while the other two
// hold their steps, every carriage read at the substep rate (its encoder with
// sweep.read_encoders); column j is H1 of each carriage against carriage j's commanded staircase,
// divided by the zero-order hold. `also` (optional): the same records' H1 on a second grid whose
// lines are among `grid`'s (the centre's q / q_d on the validation grid from the centre sweeps).
struct AssemblyH1 {
  std::vector<Eigen::Matrix3cd> h;       // on grid
  std::vector<Eigen::Matrix3cd> h_also;  // on also (empty without it)
};
Result<AssemblyH1> measure_assembly_h1(const DeltaPlantParams& truth,
                                       const Eigen::Vector3d& position_mm,
                                       const model::FrequencyGrid& grid, uint64_t seed,
                                       const SweepSpec& sweep,
                                       const model::FrequencyGrid* also = nullptr);

// simulate_measurements with every dynamic test that reads carriages made in the time domain from
// the encoders (sweep.read_encoders is forced on): both carriage experiments (Sect. IV-A), the
// centre sweeps (IV-B, q_i / X_j = (q / q_d) Jbar^-1) and the four validation positions (IV-C), on
// the full nonlinear plant (rigid tilting effector, elastic arms, gravity, 80 steps/mm staircase)
// with truth.encoder's quantisation, noise and delay, none of which the LPV model contains. The
// impact test stays the small-signal FRF of its 2-DOF rig (a hammer and an accelerometer, no
// encoder). plan.noise_rel is not used (the noise is the encoders').
Result<ident::delta::DeltaMeasurements> simulate_measurements_from_encoders(
    const DeltaPlantParams& truth, const ident::delta::MeasurementPlan& plan, SweepSpec sweep = {});

}  // namespace feedloop::sim
