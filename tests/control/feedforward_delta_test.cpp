// Delta LPV feedforward (control/feedforward/delta_lpv.hpp) on the delta paper's linear model
// itself (Eq. 29, re-linearised at the current nozzle position every period, 20x finer step):
// tracking vs u = r, LPV vs the fixed centre model at the DESIGN.md validation positions, and a
// bounded command despite the non-minimum-phase carriage zero (Eq. 34, d1 < 0).
#include <gtest/gtest.h>

#include <cstdio>

#include "control/feedforward/delta_lpv.hpp"
#include "feedforward_test_support.hpp"
#include "model/delta_kinematics.hpp"
#include "model/delta_lpv.hpp"

namespace feedloop::control {
namespace {

constexpr double kT = 1e-3;
const model::DeltaParams kParams = model::delta_table1_params();  // Table I, canonical geometry

// Grid over the print disc at two heights around the validation height z = 30 mm (the factory
// covers z_min..z_max; a test only needs the slab it moves in).
std::unique_ptr<DeltaLpvFeedforward> make(bool frozen) {
  DeltaLpvGrid g;
  g.xy_radius_mm = 100.0;
  g.xy_step_mm = 25.0;
  g.z_min_mm = 20.0;
  g.z_max_mm = 40.0;
  g.z_step_mm = 20.0;
  g.freeze_at_centre = frozen;
  LpvDesignOptions opt;
  opt.period_s = kT;
  opt.preview_samples = 20;
  auto ff = DeltaLpvFeedforward::create(kParams, model::ForceTransform::Paper, g, opt);
  EXPECT_TRUE(ff.ok()) << (ff.ok() ? "" : ff.error().message);
  return std::move(ff.value());
}

// The LPV plant: Eq. 29 at the nozzle position given by forward kinematics of the carriages.
fftest::FineSim plant() {
  static const model::DeltaLpvModel mdl = model::DeltaLpvModel::create(kParams).value();
  return fftest::FineSim(
      [](const Eigen::VectorXd& q_mm) {
        const Eigen::Vector3d x = model::forward_kinematics(kParams.geometry, Eigen::Vector3d(q_mm)).value();
        return mdl.state_space(mdl.at(x).value()).value();
      },
      kT);
}

// A 20 mm move along x, then one along y, through (x0, y0, 30) at 100 mm/s, 3000 mm/s^2.
struct DeltaPlan {
  double x0, y0;
  fftest::Trapezoid mx{-10.0, 10.0, 100.0, 3000.0, 0.05};  // at rest for > P periods first
  fftest::Trapezoid my{-10.0, 10.0, 100.0, 3000.0, 0.35};
  FeedforwardInput operator()(int k) const {
    const double t = k * kT;
    const Eigen::Vector3d X(x0 + mx.at(t), y0 + (t < 0.33 ? -10.0 : my.at(t)), 30.0);
    const Eigen::Vector3d q = model::inverse_kinematics(kParams.geometry, X).value();
    FeedforwardInput in;
    in.r_mm = {q.x(), q.y(), q.z(), 0.0};
    in.nozzle_mm = {X.x(), X.y(), X.z()};
    return in;
  }
};
constexpr int kSteps = 700;

struct Case {
  double x, y;
};
const Case kValidation[] = {{0, 0}, {-80, 0}, {40, -69}, {40, 69}};  // DESIGN.md, z = 30 mm

TEST(DeltaLpvFeedforward, LpvTracksTenTimesBetterThanUEqualsRAndBeatsTheCentreModel) {
  auto lpv = make(false), centre = make(true);
  EXPECT_EQ(lpv->grid_points(), 9 * 9 * 2);
  EXPECT_EQ(centre->grid_points(), 2);
  for (const Case& c : kValidation) {
    const DeltaPlan plan{c.x, c.y};
    auto s0 = plant(), s1 = plant(), s2 = plant();
    const fftest::TrackingError open = fftest::run(nullptr, s0, 3, kSteps, plan);
    const fftest::TrackingError e_lpv = fftest::run(lpv.get(), s1, 3, kSteps, plan);
    const fftest::TrackingError e_cen = fftest::run(centre.get(), s2, 3, kSteps, plan);
    std::printf("delta at (%4.0f,%4.0f,30): u=r max %.1f um rms %.1f | LPV max %.3f rms %.3f | centre model "
                "max %.3f rms %.3f um | max |u-r| %.3f mm\n",
                c.x, c.y, open.max_um, open.rms_um, e_lpv.max_um, e_lpv.rms_um, e_cen.max_um, e_cen.rms_um,
                e_lpv.max_abs_u_minus_r_mm);
    EXPECT_GT(open.max_um / e_lpv.max_um, 10.0) << c.x << "," << c.y;
    EXPECT_GT(open.rms_um / e_lpv.rms_um, 10.0) << c.x << "," << c.y;
    if (c.x != 0 || c.y != 0) {
      EXPECT_LT(e_lpv.rms_um * 2.0, e_cen.rms_um) << c.x << "," << c.y;
      EXPECT_LT(e_lpv.max_um * 2.0, e_cen.max_um) << c.x << "," << c.y;
    }
    // Non-minimum-phase zero handled: the command stays near the reference and settles.
    EXPECT_LT(e_lpv.max_abs_u_minus_r_mm, 2.0);
    EXPECT_LT(e_lpv.final_u_minus_r_mm, 1e-6);
  }
}

TEST(DeltaLpvFeedforward, StepReferenceGivesABoundedCommandAtEveryValidationPosition) {
  // The hardest input for an inverse of a non-minimum-phase model: a 0.1 mm step on carriage A.
  auto lpv = make(false);
  for (const Case& c : kValidation) {
    const Eigen::Vector3d X(c.x, c.y, 30.0);
    const Eigen::Vector3d q = model::inverse_kinematics(kParams.geometry, X).value();
    FeedforwardInput at;
    at.r_mm = {q.x(), q.y(), q.z(), 0.0};
    at.nozzle_mm = {X.x(), X.y(), X.z()};
    lpv->reset(at);
    JointArray u{};
    double peak = 0, tail = 0;
    for (int k = 0; k < 2000; ++k) {
      FeedforwardInput in = at;
      if (k >= 50) in.r_mm[0] += 0.1;
      lpv->step(in, u);
      for (int j = 0; j < 3; ++j) {
        ASSERT_TRUE(std::isfinite(u[static_cast<size_t>(j)]));
        const double dev = std::abs(u[static_cast<size_t>(j)] - in.r_mm[static_cast<size_t>(j)]);
        peak = std::max(peak, dev);
        if (k >= 1900) tail = std::max(tail, dev);
      }
    }
    std::printf("delta step 0.1 mm at (%4.0f,%4.0f,30): peak |u - r| %.3f mm, after 1.9 s %.2e mm\n", c.x, c.y,
                peak, tail);
    // Bounded: an exact inverse would grow like exp(674 t) (the RHP zero); this one peaks at ~11x
    // the step (a step has unbounded acceleration: the worst case) and settles.
    EXPECT_LT(peak, 1.5);
    EXPECT_LT(tail, 1e-6);  // and it settles
  }
}

// The effector's weight: at rest off the centre the command is the reference plus each carriage's
// extra belt stretch, (tau_i(X) - tau_i(0, 0, z)) / k. Checked against the statics solved directly
// (arm tensions along the arms balancing the weight, their vertical parts on the carriages), not
// against the virtual-work formula the feedforward uses; none at the centre, none when frozen.
TEST(DeltaLpvFeedforward, WeightStretchOffTheCentreIsCommandedAway) {
  DeltaLpvGrid g;
  g.z_min_mm = 20.0;
  g.z_max_mm = 40.0;
  g.z_step_mm = 20.0;
  LpvDesignOptions opt;
  opt.period_s = kT;
  opt.preview_samples = 20;
  auto lpv = DeltaLpvFeedforward::create(kParams, model::ForceTransform::VirtualWork, g, opt, 9.81);
  g.freeze_at_centre = true;
  auto centre = DeltaLpvFeedforward::create(kParams, model::ForceTransform::VirtualWork, g, opt, 9.81);
  ASSERT_TRUE(lpv.ok() && centre.ok());
  const double weight_n = (kParams.m1_effective_kg() + kParams.m2_kg) * 9.81;
  // Vertical load on each carriage from the statics: S f = [0, 0, W], S's columns the unit
  // vectors from each effector joint up its arm to the carriage.
  auto loads = [&](const Eigen::Vector3d& x) {
    const Eigen::Vector3d q = model::inverse_kinematics(kParams.geometry, x).value();
    Eigen::Matrix3d S;
    for (int i = 0; i < 3; ++i) {
      const Eigen::Vector2d t = kParams.geometry.tower_xy_mm(i);
      S.col(i) = Eigen::Vector3d(t.x() - x.x(), t.y() - x.y(), q[i] - x.z() - kParams.geometry.nozzle_offset_mm)
                     .normalized();
    }
    const Eigen::Vector3d f = S.fullPivLu().solve(Eigen::Vector3d(0.0, 0.0, weight_n));  // tensions
    Eigen::Vector3d down;
    for (int i = 0; i < 3; ++i) down[i] = f[i] * S(2, i);
    return down;
  };
  for (const Eigen::Vector3d& x : {Eigen::Vector3d(-80, 0, 30), Eigen::Vector3d(40, -69, 30),
                                   Eigen::Vector3d(40, 69, 30), Eigen::Vector3d(0, 0, 30)}) {
    FeedforwardInput at;
    const Eigen::Vector3d q = model::inverse_kinematics(kParams.geometry, x).value();
    at.r_mm = {q[0], q[1], q[2], 0.0};
    at.nozzle_mm = {x.x(), x.y(), x.z()};
    (*lpv)->reset(at);
    (*centre)->reset(at);
    JointArray u{}, uc{};
    for (int k = 0; k < 50; ++k) {
      (*lpv)->step(at, u);
      (*centre)->step(at, uc);
    }
    const Eigen::Vector3d extra = (loads(x) - loads(Eigen::Vector3d(0, 0, x.z()))) / kParams.k_n_m * 1e3;
    for (int i = 0; i < 3; ++i) {
      const size_t j = static_cast<size_t>(i);
      EXPECT_NEAR(u[j] - at.r_mm[j], extra[i], 1e-4) << "carriage " << i << " at " << x.transpose();
      EXPECT_NEAR(uc[j], at.r_mm[j], 1e-8);  // the centre's model: no weight term
    }
    std::printf("(%.0f, %.0f, %.0f): weight stretch commanded %+.4f %+.4f %+.4f mm\n", x.x(), x.y(), x.z(),
                u[0] - at.r_mm[0], u[1] - at.r_mm[1], u[2] - at.r_mm[2]);
    if (x.x() == -80) {
      EXPECT_GT(extra.cwiseAbs().maxCoeff(), 5e-3);  // microns: it matters
    }
  }
}

}  // namespace
}  // namespace feedloop::control
