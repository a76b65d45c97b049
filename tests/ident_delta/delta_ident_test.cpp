// The delta paper's identification procedure (Sect. IV) on simulated measurements at (0,0,30):
// identified parameters against the simulator's true ones, predictions at the three other
// validation positions against the paper's Table II averages, and which force transformation
// the measurements support.
#include <cmath>
#include <cstdio>

#include <gtest/gtest.h>

#include "ident/delta/delta_ident.hpp"
#include "ident/delta/rational_fit.hpp"
#include "sim/experiments/delta_measurements.hpp"

namespace feedloop::ident::delta {
namespace {

using model::ForceTransform;

double rel_err(double got, double want) { return std::abs(got / want - 1.0); }

// One simulated campaign shared by the tests (the plant linearisations are the costly part).
const DeltaMeasurements& measurements() {
  static const DeltaMeasurements m = [] {
    auto r = sim::simulate_measurements(sim::DeltaPlantParams{}, MeasurementPlan{});
    EXPECT_TRUE(r.ok()) << (r.ok() ? "" : r.error().message);
    return r.ok() ? *r : DeltaMeasurements{};
  }();
  return m;
}

TEST(RationalFit, RecoversAKnownFourthOrderTransferFunction) {
  const model::TransferFunction truth{{-2e4, 3e6, 1.7e10}, {1.0, 90.0, 7.5e5, 2.1e7, 1.7e10}};
  std::vector<double> f;
  std::vector<Complex> h;
  for (double fh = 2.0; fh <= 300.0; fh += 1.0) {
    f.push_back(fh);
    h.push_back(truth.at_hz(fh));
  }
  auto fit = fit_rational(f, h, RationalFitSpec{});
  ASSERT_TRUE(fit.ok()) << fit.error().message;
  for (size_t i = 0; i < truth.den.size(); ++i) EXPECT_LT(rel_err(fit->den[i], truth.den[i]), 1e-6) << i;
  for (size_t i = 0; i < truth.num.size(); ++i) EXPECT_LT(rel_err(fit->num[i], truth.num[i]), 1e-6) << i;
}

TEST(RationalFit, RejectsBadInput) {
  const std::vector<double> f{1.0, 2.0};
  const std::vector<Complex> h{1.0, 1.0};
  EXPECT_FALSE(fit_rational(f, h, RationalFitSpec{}).ok());  // 4 equations, 7 unknowns
  EXPECT_FALSE(fit_rational(f, std::vector<Complex>{1.0}, RationalFitSpec{}).ok());
}

TEST(DeltaIdent, MeasurementPlanIsValidated) {
  MeasurementPlan plan;
  plan.m_add_kg = 0.0;
  EXPECT_FALSE(sim::simulate_measurements(sim::DeltaPlantParams{}, plan).ok());
  plan = MeasurementPlan{};
  plan.validation_mm[0] = {400.0, 0.0, 30.0};  // out of reach
  EXPECT_FALSE(sim::simulate_measurements(sim::DeltaPlantParams{}, plan).ok());
}

TEST(DeltaIdent, CarriageAndEffectorParametersMatchTheSimulator) {
  const model::DeltaParams truth;
  auto c = identify_carriage(measurements());
  ASSERT_TRUE(c.ok()) << c.error().message;
  std::printf("carriage: m %.4f (true %.4f) m_c %.4f k %.4g c %.3f b %.3f d0 %.4g d1 %.2f d2 %.2f  wn %.1f wn' %.1f "
              "zeta %.4f rms %.2e\n",
              c->m_kg, truth.m_kg(), c->m_c_kg, c->k_n_m, c->c_n_s_m, c->b_n_s_m, c->d0_per_s2, c->d1_per_s,
              c->d2_per_s, c->omega_n_rad_s, c->omega_n_added_rad_s, c->zeta, c->rms_rel);
  EXPECT_LT(rel_err(c->m_c_kg, truth.m_c_kg), 0.01);
  EXPECT_LT(rel_err(c->k_n_m, truth.k_n_m), 0.01);
  EXPECT_LT(rel_err(c->c_n_s_m + c->b_n_s_m, truth.c_n_s_m + truth.b_n_s_m), 0.02);
  EXPECT_LT(rel_err(c->c_n_s_m, truth.c_n_s_m), 0.10);
  EXPECT_LT(rel_err(c->d0_per_s2, truth.d0_per_s2), 0.01);
  EXPECT_LT(rel_err(c->d1_per_s, truth.d1_per_s), 0.01);
  EXPECT_LT(rel_err(c->d2_per_s, truth.d2_per_s), 0.02);
  // Eq. 41 with the paper's 200 g: omega_n' = sqrt(k / (m + m_add)).
  EXPECT_LT(rel_err(c->omega_n_added_rad_s, std::sqrt(truth.k_n_m / (truth.m_kg() + 0.2))), 0.01);

  auto e = identify_effector(measurements());
  ASSERT_TRUE(e.ok()) << e.error().message;
  std::printf("effector: m1 %.4f m2 %.4f wz %.1f wp %.1f rms %.2e\n", e->m1_kg, e->m2_kg, e->omega_z_rad_s,
              e->omega_p_rad_s, e->rms_rel);
  EXPECT_LT(rel_err(e->m1_kg, truth.m1_kg), 0.01);
  EXPECT_LT(rel_err(e->m2_kg, truth.m2_kg), 0.02);
}

TEST(DeltaIdent, VirtualWorkFitsTheCentreAndPredictsBetterThanThePaper) {
  const model::DeltaParams truth;
  auto vw = identify(measurements(), ForceTransform::VirtualWork);
  auto paper = identify(measurements(), ForceTransform::Paper);
  ASSERT_TRUE(vw.ok()) << vw.error().message;
  ASSERT_TRUE(paper.ok()) << paper.error().message;
  for (const auto* id : {&*vw, &*paper})
    std::printf("%-12s b_j %.2f %.2f %.2f  k_j %.4g %.4g %.4g  centre rms %.4f (%d evals)\n", to_string(id->form),
                id->coupling.b_n_s_m.x(), id->coupling.b_n_s_m.y(), id->coupling.b_n_s_m.z(), id->coupling.k_n_m.x(),
                id->coupling.k_n_m.y(), id->coupling.k_n_m.z(), id->coupling.rms_rel, id->coupling.evaluations);
  // The simulator follows rigid-body physics: virtual work explains the centre data far better.
  EXPECT_LT(vw->coupling.rms_rel, 0.5 * paper->coupling.rms_rel);
  // With the default (finite) arms the effector tilts a little, which no form of Eq. 29 has:
  // b_j and k_j absorb some of it (measured: k_x +20 %, k_y +40 %, k_z 0 %, b_j within 25 %).
  EXPECT_LT(rel_err(vw->params.k_x_n_m, truth.k_x_n_m), 0.35);
  EXPECT_LT(rel_err(vw->params.k_y_n_m, truth.k_y_n_m), 0.60);
  EXPECT_LT(rel_err(vw->params.k_z_n_m, truth.k_z_n_m), 0.10);
  for (int j = 0; j < 3; ++j)
    EXPECT_LT(rel_err(vw->coupling.b_n_s_m[j], Eigen::Vector3d(truth.b_x_n_s_m, truth.b_y_n_s_m, truth.b_z_n_s_m)[j]), 0.40);

  // Diagnostic: let one factor on the weighed effector masses float. Virtual work keeps the scale's
  // masses; the paper's double split (m_e/9 per carriage instead of m_e/3) asks for about 3x.
  auto scale_vw = identify_coupling(measurements(), vw->params, ForceTransform::VirtualWork, true);
  auto scale_paper = identify_coupling(measurements(), paper->params, ForceTransform::Paper, true);
  ASSERT_TRUE(scale_vw.ok() && scale_paper.ok());
  std::printf("effector mass factor the centre data ask for: virtual work %.3f (rms %.4f), paper %.3f (rms %.4f)\n",
              scale_vw->mass_scale, scale_vw->rms_rel, scale_paper->mass_scale, scale_paper->rms_rel);
  EXPECT_LT(std::abs(scale_vw->mass_scale - 1.0), 0.1);
  EXPECT_GT(scale_paper->mass_scale, 2.0);

  auto tv = validate(measurements(), vw->params, ForceTransform::VirtualWork);
  auto tp = validate(measurements(), paper->params, ForceTransform::Paper);
  ASSERT_TRUE(tv.ok()) << tv.error().message;
  ASSERT_TRUE(tp.ok()) << tp.error().message;
  // The paper's Table II averages (magnitude, phase) for A, B, C.
  const double paper_mag[3] = {67.7, 78.1, 68.7}, paper_phase[3] = {80.0, 82.3, 84.4};
  for (int i = 0; i < 3; ++i) {
    std::printf("%c: vw avg mu_acc mag %.1f phase %.1f | paper-form %.1f %.1f | paper's Table II %.1f %.1f\n", "ABC"[i],
                tv->avg_acc_mag_pct[i], tv->avg_acc_phase_pct[i], tp->avg_acc_mag_pct[i], tp->avg_acc_phase_pct[i],
                paper_mag[i], paper_phase[i]);
    EXPECT_GT(tv->avg_acc_mag_pct[i], paper_mag[i]);
    EXPECT_GT(tv->avg_acc_phase_pct[i], paper_phase[i]);
    EXPECT_GT(tv->avg_acc_mag_pct[i], tp->avg_acc_mag_pct[i]);
  }
  // Along each carriage's line of action (Table III diagonal) the LPV prediction beats the fixed
  // centre model.
  for (int i = 0; i < 3; ++i) {
    std::printf("%c on its line of action: error reduction mag %.1f %% phase %.1f %%\n", "ABC"[i],
                tv->reduction_mag_pct(i, i), tv->reduction_phase_pct(i, i));
    EXPECT_GT(tv->reduction_mag_pct(i, i), 0.0);
  }
}

// 2 % complex noise on every measured FRF point: the procedure still beats the paper's Table II
// magnitude averages by a wide margin and keeps the carriage and effector parameters within 2 %.
TEST(DeltaIdent, TwoPercentNoiseStillBeatsThePaper) {
  MeasurementPlan plan;
  plan.noise_rel = 0.02;
  plan.seed = 7;
  auto meas = sim::simulate_measurements(sim::DeltaPlantParams{}, plan);
  ASSERT_TRUE(meas.ok()) << meas.error().message;
  auto id = identify(*meas, ForceTransform::VirtualWork);
  ASSERT_TRUE(id.ok()) << id.error().message;
  const model::DeltaParams truth;
  EXPECT_LT(rel_err(id->params.m_c_kg, truth.m_c_kg), 0.02);
  EXPECT_LT(rel_err(id->params.k_n_m, truth.k_n_m), 0.02);
  EXPECT_LT(rel_err(id->params.m1_kg, truth.m1_kg), 0.02);
  EXPECT_LT(rel_err(id->params.d1_per_s, truth.d1_per_s), 0.02);
  auto t = validate(*meas, id->params, ForceTransform::VirtualWork);
  ASSERT_TRUE(t.ok()) << t.error().message;
  const double paper_mag[3] = {67.7, 78.1, 68.7};
  for (int i = 0; i < 3; ++i) {
    std::printf("noisy %c: avg mu_acc mag %.1f phase %.1f\n", "ABC"[i], t->avg_acc_mag_pct[i], t->avg_acc_phase_pct[i]);
    EXPECT_GT(t->avg_acc_mag_pct[i], paper_mag[i] + 10.0);
  }
}

// A different machine (heavier carriage, stiffer belt, other electrical mode, other effector):
// nothing in the procedure is tuned to Table I.
TEST(DeltaIdent, AnotherMachineIsIdentifiedToo) {
  sim::DeltaPlantParams other;
  model::DeltaParams& t = other.model;
  t.m_c_kg = 0.26;
  t.k_n_m = 1.6e5;
  t.c_n_s_m = 8.0;
  t.b_n_s_m = 9.0;
  t.d0_per_s2 = 2.2e5;
  t.d1_per_s = -150.0;
  t.d2_per_s = 50.0;
  t.m1_kg = 0.40;
  t.m2_kg = 0.16;
  t.k_x_n_m = 6.0e3;
  t.k_y_n_m = 4.5e3;
  t.k_z_n_m = 9.0e4;
  t.b_x_n_s_m = 30.0;
  t.b_y_n_s_m = 25.0;
  t.b_z_n_s_m = 40.0;
  other.arm_stiffness_n_m = 1e9;  // the virtual-work structure exactly: b_j, k_j must come back
  auto meas = sim::simulate_measurements(other, MeasurementPlan{});
  ASSERT_TRUE(meas.ok()) << meas.error().message;
  auto id = identify(*meas, ForceTransform::VirtualWork);
  ASSERT_TRUE(id.ok()) << id.error().message;
  const model::DeltaParams& p = id->params;
  EXPECT_LT(rel_err(p.m_c_kg, t.m_c_kg), 0.01);
  EXPECT_LT(rel_err(p.k_n_m, t.k_n_m), 0.01);
  EXPECT_LT(rel_err(p.c_n_s_m, t.c_n_s_m), 0.05);
  EXPECT_LT(rel_err(p.b_n_s_m, t.b_n_s_m), 0.05);
  EXPECT_LT(rel_err(p.d0_per_s2, t.d0_per_s2), 0.01);
  EXPECT_LT(rel_err(p.d1_per_s, t.d1_per_s), 0.01);
  EXPECT_LT(rel_err(p.d2_per_s, t.d2_per_s), 0.01);
  EXPECT_LT(rel_err(p.m1_kg, t.m1_kg), 0.01);
  EXPECT_LT(rel_err(p.m2_kg, t.m2_kg), 0.01);
  const Eigen::Vector3d b(t.b_x_n_s_m, t.b_y_n_s_m, t.b_z_n_s_m), k(t.k_x_n_m, t.k_y_n_m, t.k_z_n_m);
  std::printf("other machine: m_c %.4f k %.4g b_j %.2f %.2f %.2f k_j %.4g %.4g %.4g\n", p.m_c_kg, p.k_n_m,
              id->coupling.b_n_s_m.x(), id->coupling.b_n_s_m.y(), id->coupling.b_n_s_m.z(), id->coupling.k_n_m.x(),
              id->coupling.k_n_m.y(), id->coupling.k_n_m.z());
  for (int j = 0; j < 3; ++j) {
    EXPECT_LT(rel_err(id->coupling.k_n_m[j], k[j]), 0.05) << "k_" << "xyz"[j];
    EXPECT_LT(rel_err(id->coupling.b_n_s_m[j], b[j]), 0.10) << "b_" << "xyz"[j];
  }
}

// With very stiff arms the simulator is the virtual-work model (tests/sim/delta_frf_test.cpp), so
// the least squares of step 3 must return b_j and k_j themselves.
TEST(DeltaIdent, StiffArmsGiveBackTheCouplingParameters) {
  sim::DeltaPlantParams stiff;
  stiff.arm_stiffness_n_m = 1e9;
  auto meas = sim::simulate_measurements(stiff, MeasurementPlan{});
  ASSERT_TRUE(meas.ok()) << meas.error().message;
  auto id = identify(*meas, ForceTransform::VirtualWork);
  ASSERT_TRUE(id.ok()) << id.error().message;
  const model::DeltaParams& t = stiff.model;
  const Eigen::Vector3d b(t.b_x_n_s_m, t.b_y_n_s_m, t.b_z_n_s_m), k(t.k_x_n_m, t.k_y_n_m, t.k_z_n_m);
  std::printf("stiff arms: b_j %.2f %.2f %.2f k_j %.4g %.4g %.4g centre rms %.4f\n", id->coupling.b_n_s_m.x(),
              id->coupling.b_n_s_m.y(), id->coupling.b_n_s_m.z(), id->coupling.k_n_m.x(), id->coupling.k_n_m.y(),
              id->coupling.k_n_m.z(), id->coupling.rms_rel);
  for (int j = 0; j < 3; ++j) {
    EXPECT_LT(rel_err(id->coupling.k_n_m[j], k[j]), 0.05) << "k_" << "xyz"[j];
    EXPECT_LT(rel_err(id->coupling.b_n_s_m[j], b[j]), 0.10) << "b_" << "xyz"[j];
  }
  EXPECT_LT(id->coupling.rms_rel, 0.01);

  // The paper's own route (Eq. 66 fits, Eq. 68 coefficient matching) on the same data: with
  // alpha_ji as published, carriages B and C get negative alpha for x and y and the least squares
  // returns non-physical b_j, k_j; with alpha per unit of the carriage's own motion it works,
  // less precisely than the Eq. 29 least squares. z (all carriages move alike) is right either way.
  auto published = identify_coupling_eq68(*meas, id->params, ForceTransform::VirtualWork, Eq68Alpha::Published);
  auto corrected = identify_coupling_eq68(*meas, id->params, ForceTransform::VirtualWork, Eq68Alpha::PerCarriageMotion);
  ASSERT_TRUE(published.ok() && corrected.ok());
  std::printf("Eq. 68 published alpha: b_j %.1f %.1f %.1f k_j %.4g %.4g %.4g (physical %d); per carriage motion: b_j "
              "%.2f %.2f %.2f k_j %.4g %.4g %.4g rms %.4f\n",
              published->b_n_s_m.x(), published->b_n_s_m.y(), published->b_n_s_m.z(), published->k_n_m.x(),
              published->k_n_m.y(), published->k_n_m.z(), published->physical, corrected->b_n_s_m.x(),
              corrected->b_n_s_m.y(), corrected->b_n_s_m.z(), corrected->k_n_m.x(), corrected->k_n_m.y(),
              corrected->k_n_m.z(), corrected->rms_rel);
  EXPECT_FALSE(published->physical);
  EXPECT_LT(rel_err(published->k_n_m.z(), k.z()), 0.01);
  ASSERT_TRUE(corrected->physical);
  EXPECT_LT(rel_err(corrected->k_n_m.z(), k.z()), 0.01);
  for (int j = 0; j < 2; ++j) EXPECT_LT(rel_err(corrected->k_n_m[j], k[j]), 0.15) << "k_" << "xy"[j];
  EXPECT_GT(corrected->rms_rel, id->coupling.rms_rel);
}

}  // namespace
}  // namespace feedloop::ident::delta
