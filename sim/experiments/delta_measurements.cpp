// The delta paper's Sect. IV measurements on the simulated delta (see delta_measurements.hpp).
#include "sim/experiments/delta_measurements.hpp"

#include <array>
#include <cmath>
#include <memory>
#include <numbers>
#include <string>

#include "core/rng.hpp"
#include "ident/frf.hpp"
#include "model/delta_kinematics.hpp"
#include "model/frf_set.hpp"
#include "model/lti.hpp"
#include "sim/linearize.hpp"
#include "sim/step_driver.hpp"

namespace feedloop::sim {

namespace {

using Complex = std::complex<double>;
constexpr double kTwoPi = 2.0 * std::numbers::pi;

Complex jw(double f_hz) {
  return {0.0, kTwoPi * f_hz};
}

Status check_grid(const model::FrequencyGrid& g, const char* name) {
  if (Status s = g.validate(); !s) return Error{std::string(name) + ": " + s.error().message, {}};
  return {};
}

// Small-signal FRF matrices q / q_d of a plant built from p.
Result<std::vector<Eigen::Matrix3cd>> plant_frf(const DeltaPlantParams& p,
                                                const model::FrequencyGrid& grid) {
  auto plant = DeltaPlant::create(p);
  if (!plant.ok()) return plant.error();
  const LinearModel lin = (*plant)->linearize();
  std::vector<Eigen::Matrix3cd> out;
  out.reserve(static_cast<size_t>(grid.size()));
  for (int k = 0; k < grid.size(); ++k) out.emplace_back(frequency_response(lin, grid.at_hz(k)));
  return out;
}

void add_noise(Complex& h, double noise_rel, Rng& rng) {
  if (noise_rel <= 0.0) return;
  const double s = noise_rel / std::numbers::sqrt2;
  h *= Complex(1.0 + s * rng.gaussian(), s * rng.gaussian());
}

model::FrfSet to_set(const model::FrequencyGrid& grid, std::vector<Eigen::Matrix3cd> h) {
  model::FrfSet set;
  set.freq_hz = grid.points_hz();
  set.h = std::move(h);
  return set;
}

}  // namespace

Result<ident::delta::DeltaMeasurements> simulate_measurements(
    const DeltaPlantParams& truth, const ident::delta::MeasurementPlan& plan) {
  if (Status s = check_grid(plan.carriage_grid, "carriage_grid"); !s) return s.error();
  if (Status s = check_grid(plan.hammer_grid, "hammer_grid"); !s) return s.error();
  if (Status s = check_grid(plan.centre_grid, "centre_grid"); !s) return s.error();
  if (Status s = check_grid(plan.validation_grid, "validation_grid"); !s) return s.error();
  if (!(plan.m_add_kg > 0.0)) return Error{"measurement plan: m_add_kg must be > 0", {}};
  if (plan.hammer_axis < 0 || plan.hammer_axis > 2)
    return Error{"measurement plan: hammer_axis must be 0, 1 or 2", {}};
  if (!(plan.noise_rel >= 0.0)) return Error{"measurement plan: noise_rel must be >= 0", {}};
  if (Status s = validate(truth); !s) return s.error();

  ident::delta::DeltaMeasurements m;
  m.plan = plan;
  Rng rng(plan.seed);

  // Sect. IV-A: effector detached (its arms carry no force), one forearm pair's half on the
  // carriage.
  DeltaPlantParams detached = truth;
  detached.arm_stiffness_n_m = plan.detached_arm_stiffness_n_m;
  detached.arm_damping_n_s_m = 0.0;
  detached.gravity_m_s2 = 0.0;  // the detached effector would fall; gravity does not enter the FRF
  detached.initial_nozzle_mm = plan.centre_mm;
  for (int pass = 0; pass < 2; ++pass) {
    DeltaPlantParams p = detached;
    if (pass == 1) p.model.m_c_kg += plan.m_add_kg;
    auto g = plant_frf(p, plan.carriage_grid);
    if (!g.ok()) return Error{"carriage measurement: " + g.error().message, {}};
    auto& dst = pass == 0 ? m.carriage : m.carriage_added;
    for (const auto& gm : *g) {
      Complex h = gm(0, 0);
      add_noise(h, plan.noise_rel, rng);
      dst.push_back(h);
    }
  }

  // Sect. IV-B impact test: the isolated effector along one axis, m1 (hit, measured) and m2 on
  // k_j, b_j (Eq. 50-55 without arms): states [x1, v1, x2, v2], input F_h, output x1''.
  {
    const model::DeltaParams& mp = truth.model;
    const double m1 = mp.m1_effective_kg(), m2 = mp.m2_kg;
    const int j = plan.hammer_axis;
    const double kj =
        std::array<double, 3>{mp.k_x_n_m, mp.k_y_n_m, mp.k_z_n_m}[static_cast<size_t>(j)];
    const double bj =
        std::array<double, 3>{mp.b_x_n_s_m, mp.b_y_n_s_m, mp.b_z_n_s_m}[static_cast<size_t>(j)];
    model::StateSpace ss;
    ss.A = Eigen::MatrixXd::Zero(4, 4);
    ss.A(0, 1) = 1.0;
    ss.A(1, 0) = -kj / m1;
    ss.A(1, 1) = -bj / m1;
    ss.A(1, 2) = kj / m1;
    ss.A(1, 3) = bj / m1;
    ss.A(2, 3) = 1.0;
    ss.A(3, 0) = kj / m2;
    ss.A(3, 1) = bj / m2;
    ss.A(3, 2) = -kj / m2;
    ss.A(3, 3) = -bj / m2;
    ss.B = Eigen::MatrixXd::Zero(4, 1);
    ss.B(1, 0) = 1.0 / m1;
    ss.C = ss.A.row(1);
    ss.D = ss.B.row(1);
    for (int k = 0; k < plan.hammer_grid.size(); ++k) {
      Complex h = model::frequency_response(ss, jw(plan.hammer_grid.at_hz(k)))(0, 0);
      add_noise(h, plan.noise_rel, rng);
      m.hammer.push_back(h);
    }
  }

  // Full assembly at the centre: q / q_d, turned into pure task-axis sweeps q_d = Jbar^-1 X_d.
  DeltaPlantParams full = truth;
  full.initial_nozzle_mm = plan.centre_mm;
  auto jbar = model::jacobian(truth.model.geometry, plan.centre_mm);
  if (!jbar.ok()) return Error{"centre position: " + jbar.error().message, {}};
  const Eigen::Matrix3d jinv = jbar->inverse();
  {
    auto g = plant_frf(full, plan.centre_grid);
    if (!g.ok()) return Error{"centre measurement: " + g.error().message, {}};
    for (const auto& gm : *g) {
      Eigen::Matrix3cd h = gm * jinv;
      for (int i = 0; i < 9; ++i) add_noise(h.data()[i], plan.noise_rel, rng);
      m.centre_task.push_back(h);
    }
  }
  // Sect. IV-C: q / q_d at the four positions on the validation grid.
  for (int p = 0; p < 4; ++p) {
    full.initial_nozzle_mm =
        p == 0 ? plan.centre_mm : plan.validation_mm[static_cast<size_t>(p - 1)];
    auto g = plant_frf(full, plan.validation_grid);
    if (!g.ok()) return Error{"validation measurement: " + g.error().message, {}};
    for (auto& gm : *g)
      for (int i = 0; i < 9; ++i) add_noise(gm.data()[i], plan.noise_rel, rng);
    (p == 0 ? m.centre : m.validation[static_cast<size_t>(p - 1)]) =
        to_set(plan.validation_grid, std::move(*g));
  }

  m.m_f_kg = truth.model.m_f_kg;
  m.m_tot_kg = truth.model.m1_kg + truth.model.m2_kg;
  m.cad = model::DeltaParams{};
  m.cad.delta_x_mm = truth.model.delta_x_mm;
  m.cad.delta_y_mm = truth.model.delta_y_mm;
  m.cad.delta_z_mm = truth.model.delta_z_mm;
  m.cad.D_e_mm = truth.model.D_e_mm;
  m.cad.geometry = truth.model.geometry;
  m.cad.forearm_half_mass_on_m1 = truth.model.forearm_half_mass_on_m1;
  return m;
}

namespace {

// The commanded staircase of the driven carriage and every carriage's reading, one sample per
// substep, after one settling period.
struct SweepRecord {
  double rate_hz = 0.0;
  std::vector<double> u;
  std::array<std::vector<double>, 3> y;
};

// A random-phase multisine (one line per grid frequency, period 1 / grid step, sweep.rms_mm RMS)
// on carriage `driven`'s steps; the plant's substep is the sample rate (every step on an update
// instant).
Result<SweepRecord> run_multisine(DeltaPlant& pl, int driven, const model::FrequencyGrid& grid,
                                  uint64_t seed, const SweepSpec& sweep) {
  const DeltaPlantParams& p = pl.params();
  const double period_s = 1.0 / grid.step_hz;
  SweepRecord rec;
  rec.rate_hz = p.substep_hz;
  const auto per_period = static_cast<int>(std::llround(period_s * rec.rate_hz));
  if (std::abs(per_period / rec.rate_hz - period_s) > 1e-9 * period_s)
    return Error{"sweep: the multisine period must be a whole number of simulator substeps", {}};
  Rng rng(seed);
  std::vector<double> phase(static_cast<size_t>(grid.size()));
  for (double& ph : phase) ph = kTwoPi * rng.uniform();
  const double amp = sweep.rms_mm * std::sqrt(2.0 / grid.size());
  StepDriver drive(pl.carriage_port(driven), p.mm_per_step, 0.0, 0.0);
  const int total = (sweep.periods + 1) * per_period;
  const auto kept = static_cast<size_t>(sweep.periods * per_period);
  rec.u.reserve(kept);
  for (auto& y : rec.y) y.reserve(kept);
  const double mm_per_count = p.encoder.resolution_um * 1e-3;
  // sin(w_k t + phi_k) by rotation: one complex multiply per line per sample.
  std::vector<Complex> rot(phase.size()), cur(phase.size());
  for (size_t k = 0; k < phase.size(); ++k) {
    rot[k] = std::polar(1.0, kTwoPi * grid.at_hz(static_cast<int>(k)) / rec.rate_hz);
    cur[k] = std::polar(1.0, phase[k]);
  }
  for (int n = 1; n <= total; ++n) {
    double target = 0.0;
    for (size_t k = 0; k < cur.size(); ++k) {
      cur[k] *= rot[k];
      target += amp * cur[k].imag();
    }
    if (n % per_period == 0)  // renormalise against rounding drift once a period
      for (size_t k = 0; k < cur.size(); ++k) cur[k] /= std::abs(cur[k]);
    const double t = n / rec.rate_hz;
    drive.update(t, target);
    pl.advance_to(t);
    if (n > per_period) {
      rec.u.push_back(drive.commanded_mm());
      for (int i = 0; i < 3; ++i)
        rec.y[static_cast<size_t>(i)].push_back(
            sweep.read_encoders
                ? static_cast<double>(pl.carriage_port(i).read_encoder_counts(t)) * mm_per_count
                : pl.carriage_rel_mm(i));
    }
  }
  return rec;
}

// H1 of y against the staircase u (rectangular window, one period per segment), divided by the
// zero-order hold of the staircase, (1 - e^{-jwT}) / (jwT).
Result<std::vector<Complex>> h1_over_zoh(const SweepRecord& rec, const std::vector<double>& y,
                                         const model::FrequencyGrid& grid, double period_s) {
  ident::WelchOptions opt;
  opt.segment_s = period_s;
  opt.overlap = 0.0;
  opt.window = ident::FrfWindow::kRectangular;
  opt.detrend = false;
  auto est = ident::estimate_frf_h1(rec.u, y, rec.rate_hz, grid, opt);
  if (!est.ok()) return Error{"sweep H1: " + est.error().message, {}};
  std::vector<Complex> h(est->h1.size());
  const double dt = 1.0 / rec.rate_hz;
  for (size_t k = 0; k < h.size(); ++k) {
    const double w = kTwoPi * grid.at_hz(static_cast<int>(k));
    const Complex zoh = (1.0 - std::polar(1.0, -w * dt)) / Complex(0.0, w * dt);
    h[k] = est->h1[k] / zoh;
  }
  return h;
}

// The sweeps sample and update the drive once per substep (every step on an update instant), so
// the substep is the measurement's rate: 40 kHz unless the caller fixed one.
Result<std::unique_ptr<DeltaPlant>> sweep_plant(DeltaPlantParams p) {
  if (p.substep_hz == 0.0) p.substep_hz = 40000.0;
  return DeltaPlant::create(p);
}

}  // namespace

Result<std::vector<Complex>> measure_carriage_h1(const DeltaPlantParams& truth,
                                                 const ident::delta::MeasurementPlan& plan,
                                                 bool added_mass, const SweepSpec& sweep) {
  if (Status s = check_grid(plan.carriage_grid, "carriage_grid"); !s) return s.error();
  if (!(sweep.rms_mm > 0.0) || sweep.periods < 1)
    return Error{"sweep: rms_mm > 0 and periods >= 1 needed", {}};
  DeltaPlantParams p = truth;
  p.arm_stiffness_n_m = plan.detached_arm_stiffness_n_m;
  p.arm_damping_n_s_m = 0.0;
  p.gravity_m_s2 = 0.0;
  p.initial_nozzle_mm = plan.centre_mm;
  if (added_mass) p.model.m_c_kg += plan.m_add_kg;
  // (The detached carriage's own fastest mode would give 1 kHz, too coarse for H1 of lines up to
  // 300 Hz.)
  auto plant = sweep_plant(p);
  if (!plant.ok()) return plant.error();
  auto rec =
      run_multisine(**plant, 0, plan.carriage_grid, plan.seed + (added_mass ? 101 : 0), sweep);
  if (!rec.ok()) return rec.error();
  return h1_over_zoh(*rec, rec->y[0], plan.carriage_grid, 1.0 / plan.carriage_grid.step_hz);
}

Result<AssemblyH1> measure_assembly_h1(const DeltaPlantParams& truth,
                                       const Eigen::Vector3d& position_mm,
                                       const model::FrequencyGrid& grid, uint64_t seed,
                                       const SweepSpec& sweep, const model::FrequencyGrid* also) {
  if (Status s = check_grid(grid, "sweep grid"); !s) return s.error();
  if (!(sweep.rms_mm > 0.0) || sweep.periods < 1)
    return Error{"sweep: rms_mm > 0 and periods >= 1 needed", {}};
  if (also != nullptr &&
      (std::abs(also->step_hz - grid.step_hz) > 1e-12 || also->start_hz < grid.start_hz ||
       also->stop_hz > grid.stop_hz ||
       std::abs(std::remainder(also->start_hz - grid.start_hz, grid.step_hz)) > 1e-9))
    return Error{"sweep: the second grid's lines must be among the excited ones", {}};
  AssemblyH1 out;
  out.h.assign(static_cast<size_t>(grid.size()), Eigen::Matrix3cd::Zero());
  if (also != nullptr)
    out.h_also.assign(static_cast<size_t>(also->size()), Eigen::Matrix3cd::Zero());
  for (int j = 0; j < 3; ++j) {
    DeltaPlantParams p = truth;
    p.initial_nozzle_mm = position_mm;
    p.seed = truth.seed + 17 * static_cast<uint64_t>(j + 1);  // the encoders' noise differs per run
    auto plant = sweep_plant(p);
    if (!plant.ok()) return plant.error();
    auto rec = run_multisine(**plant, j, grid, seed + 7 * static_cast<uint64_t>(j), sweep);
    if (!rec.ok()) return rec.error();
    for (int i = 0; i < 3; ++i) {
      const auto& y = rec->y[static_cast<size_t>(i)];
      auto h = h1_over_zoh(*rec, y, grid, 1.0 / grid.step_hz);
      if (!h.ok()) return h.error();
      for (size_t k = 0; k < h->size(); ++k) out.h[k](i, j) = (*h)[k];
      if (also == nullptr) continue;
      auto ha = h1_over_zoh(*rec, y, *also, 1.0 / grid.step_hz);
      if (!ha.ok()) return ha.error();
      for (size_t k = 0; k < ha->size(); ++k) out.h_also[k](i, j) = (*ha)[k];
    }
  }
  return out;
}

Result<ident::delta::DeltaMeasurements> simulate_measurements_from_encoders(
    const DeltaPlantParams& truth, const ident::delta::MeasurementPlan& plan, SweepSpec sweep) {
  sweep.read_encoders = true;
  ident::delta::MeasurementPlan small = plan;
  small.noise_rel = 0.0;
  // The impact test and the known quantities as simulate_measurements has them; the rest replaced.
  auto m = simulate_measurements(truth, small);
  if (!m.ok()) return m.error();
  for (int pass = 0; pass < 2; ++pass) {
    auto h = measure_carriage_h1(truth, plan, pass == 1, sweep);
    if (!h.ok()) return Error{"carriage sweep: " + h.error().message, {}};
    (pass == 0 ? m->carriage : m->carriage_added) = std::move(*h);
  }
  auto jbar = model::jacobian(truth.model.geometry, plan.centre_mm);
  if (!jbar.ok()) return Error{"centre position: " + jbar.error().message, {}};
  const Eigen::Matrix3d jinv = jbar->inverse();
  auto centre = measure_assembly_h1(truth, plan.centre_mm, plan.centre_grid, plan.seed + 1000,
                                    sweep, &plan.validation_grid);
  if (!centre.ok()) return Error{"centre sweeps: " + centre.error().message, {}};
  m->centre_task.clear();
  for (const auto& h : centre->h) m->centre_task.push_back(h * jinv);
  m->centre = to_set(plan.validation_grid, std::move(centre->h_also));
  for (int p = 0; p < 3; ++p) {
    auto v =
        measure_assembly_h1(truth, plan.validation_mm[static_cast<size_t>(p)], plan.validation_grid,
                            plan.seed + 2000 + 100 * static_cast<uint64_t>(p), sweep);
    if (!v.ok()) return Error{"validation sweeps: " + v.error().message, {}};
    m->validation[static_cast<size_t>(p)] = to_set(plan.validation_grid, std::move(v->h));
  }
  m->plan = plan;
  return m;
}

}  // namespace feedloop::sim
