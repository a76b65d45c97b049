// The off-nominal DC-motor plant (maneuver/offnominal_plant.hpp): with every effect off it is the
// controller's model; each effect does what its equation says (drive limits cap the force, the
// belt rings at its mode, friction holds below breakaway, the encoder quantises and delays); and
// the maneuvering servo on a drawn machine stays on the path with its limits acting.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "maneuver/controller.hpp"
#include "maneuver/gcode_path.hpp"
#include "maneuver/offnominal_plant.hpp"
#include "maneuver/simulation.hpp"
#include "maneuver/test_part.hpp"

namespace feedloop::maneuver {
namespace {

constexpr double kPi = 3.14159265358979323846;

TEST(OffNominalPlant, WithEveryEffectOffItIsTheControllersModel) {
  const CartesianDcPlant model;
  NominalSampledPlant nominal(model, 1e-5);
  OffNominalPlant off{OffNominalParams{}};
  const Vec3 start(0.1, 0.05, 0.02);
  nominal.reset(start);
  off.reset(start);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> volts(-5.0, 5.0);
  double worst_m = 0.0;
  for (int k = 0; k < 2000; ++k) {  // 0.2 s of random voltages held 0.1 ms each
    Vec3 v(volts(rng), volts(rng), volts(rng) + model.gravity_offset_v());
    nominal.advance(v, 1e-4);
    off.advance(v, 1e-4);
    worst_m = std::max(worst_m, (nominal.nozzle_m() - off.nozzle_m()).norm());
    ASSERT_LT((nominal.measure().x2_m_s - off.measure().x2_m_s).norm(), 1e-9);
  }
  EXPECT_LT(worst_m, 1e-10);
  EXPECT_GT((nominal.nozzle_m() - start).norm(), 1e-4);  // it moved: not a comparison of two rests
}

TEST(OffNominalPlant, DriveLimitsCapTheForce) {
  OffNominalParams p;
  p.voltage_limit_v = 24.0;
  p.force_limit_n = 40.0;
  OffNominalPlant plant(p);
  plant.reset(Vec3::Zero());
  const double m_x_kg = p.nominal.m_n_kg + p.nominal.j_m_kg_m2 / (p.nominal.r_m * p.nominal.r_m);
  const double g_offset = CartesianDcPlant{}.gravity_offset_v();
  for (int k = 0; k < 100; ++k) {  // 10 ms at 100 V asked
    plant.advance(Vec3(100.0, 1.0, g_offset), 1e-4);
    EXPECT_TRUE(plant.limited());
  }
  const double v_x = plant.nozzle_velocity_m_s().x();
  // 40 N on 0.45 kg less viscous drag: at most 40/0.45 m/s^2 over 10 ms = 0.889 m/s; without the
  // limits 100 V would give 1000 N, 22 m/s.
  EXPECT_LT(v_x, 40.0 / m_x_kg * 0.01 * 1.001);
  EXPECT_GT(v_x, 0.8 * 40.0 / m_x_kg * 0.01);
  // y asked 1 V = 10 N: below both limits.
  plant.advance(Vec3(0.0, 1.0, g_offset), 1e-4);
  EXPECT_FALSE(plant.limited());
}

TEST(OffNominalPlant, TheBeltRingsAtItsMode) {
  OffNominalParams p;
  p.belt_stiffness_n_m = 1.0e5;
  p.belt_damping_ratio = 0.005;
  OffNominalPlant plant(p);
  plant.reset(Vec3::Zero());
  const double g_offset = CartesianDcPlant{}.gravity_offset_v();
  // A force step on x; count the sign changes of the pulley's velocity relative to the carriage
  // (the belt's stretch rate, about 0 but for the ringing) over 100 ms.
  int crossings = 0;
  double last = 0.0;
  for (int k = 0; k < 10000; ++k) {
    plant.advance(Vec3(1.0, 0.0, g_offset), 1e-5);
    const double rel =
        plant.measure().x2_m_s.x() - plant.nozzle_velocity_m_s().x();  // exact motor encoder
    if (k > 0 && rel * last < 0.0) ++crossings;
    last = rel;
  }
  const double jr2 = p.nominal.j_m_kg_m2 / (p.nominal.r_m * p.nominal.r_m);
  const double f_hz =
      std::sqrt(p.belt_stiffness_n_m * (1.0 / jr2 + 1.0 / p.nominal.m_n_kg)) / (2.0 * kPi);
  EXPECT_NEAR(crossings / 2.0 / 0.1, f_hz, 0.03 * f_hz) << "mode " << f_hz << " Hz";
}

TEST(OffNominalPlant, FrictionHoldsBelowBreakawayAndSlidesAbove) {
  OffNominalParams p;
  p.coulomb_n = 2.0;
  p.static_n = 3.0;
  OffNominalPlant plant(p);
  plant.reset(Vec3::Zero());
  const double k1 = CartesianDcPlant{}.matrices().k1_n_v;
  const double g_offset = CartesianDcPlant{}.gravity_offset_v();
  for (int k = 0; k < 1000; ++k)
    plant.advance(Vec3(2.5 / k1, 0.0, g_offset), 1e-4);  // 2.5 N < F_s for 0.1 s
  // The smoothed sign tanh(v / v_eps) creeps where F_s tanh(v / v_eps) = 2.5 N: v = 0.12 mm/s, 12
  // um in 0.1 s (stated in offnominal_plant.hpp); free of friction it would be 1.1 m/s and 56 mm.
  EXPECT_LT(std::abs(plant.nozzle_m().x()), 20e-6);
  for (int k = 0; k < 1000; ++k) plant.advance(Vec3(4.0 / k1, 0.0, g_offset), 1e-4);  // 4 N > F_s
  EXPECT_GT(plant.nozzle_m().x(), 1e-3);
}

TEST(OffNominalPlant, TheEncoderQuantisesAndDelays) {
  OffNominalParams p;
  p.encoder_resolution_m = 1e-6;
  p.measurement_delay_s = 200e-6;
  OffNominalPlant plant(p);
  plant.reset(Vec3::Zero());
  const double g_offset = CartesianDcPlant{}.gravity_offset_v();
  for (int k = 0; k < 300; ++k) plant.advance(Vec3(2.0, 0.0, g_offset), 1e-4);
  const double x = plant.measure().x1_m.x();
  const double counts = x / 1e-6;
  EXPECT_NEAR(counts, std::round(counts), 1e-6);
  const double v = plant.nozzle_velocity_m_s().x();
  const double lag_m = plant.nozzle_m().x() - x;
  EXPECT_NEAR(lag_m, v * 200e-6, 1.5e-6);  // the delay's distance, within a count and a half
}

std::vector<Vec3> fin_layer_m() {
  TestPartOptions tp;
  tp.layers = 1;
  GcodePathOptions gp;
  gp.layers = 1;
  gp.feature = "External perimeter";
  auto wp = extrusion_path_from_gcode(test_part_gcode(tp), "fin", gp);
  EXPECT_TRUE(wp.ok()) << wp.error().to_string();
  std::vector<Vec3> wp_m;
  for (const Vec3& q : *wp) wp_m.push_back(q * 1e-3);
  return wp_m;
}

Result<SimResult> on_drawn_machine(const std::vector<Vec3>& wp_m, SpeedProfile prof,
                                   const ManeuverGains& g, const SpeedParams& sp = {}) {
  const bool arc = prof == SpeedProfile::sharp_corner_arc;
  auto path = PiecewiseLinearPath::create(
      wp_m, arc ? Parameterization::arc_length : Parameterization::unit);
  EXPECT_TRUE(path.ok());
  auto speed = SpeedAssignment::create(*path, prof, sp);
  EXPECT_TRUE(speed.ok());
  const CartesianDcPlant model;  // the controller keeps Table I
  const ManeuverController ctl(model, g);
  SimOptions so;
  so.control_period_s = 5e-5;  // 20 kHz
  so.record_every = 0;
  so.split_at_waypoints = arc;
  so.max_time_s = 20.0;
  OffNominalPlant plant(draw_offnominal(1));
  return simulate_sampled(*path, *speed, ctl, plant, so);
}

// Table II's gains on a drawn machine (belt, sensing lag, limits): the belt's light pulley side
// sees K_d M / (J_m / r^2) ~ 10x the loop gain the rigid model was designed for, and the loop
// chatters against the 40 N limit most of the time; K_d 200/s (K_p 60/s) does not, and follows the
// fin's layer within 0.5 mm with the sharp-corner assignment.
TEST(OffNominalPlant, TableIIGainsChatterOnADrawnMachineLowerOnesFollow) {
  const std::vector<Vec3> wp_m = fin_layer_m();
  auto table_ii = on_drawn_machine(wp_m, SpeedProfile::sharp_corner, ManeuverGains{});
  ASSERT_TRUE(table_ii.ok()) << table_ii.error().to_string();
  EXPECT_GT(table_ii->limited_fraction, 0.5);
  ManeuverGains robust;
  robust.k_d = 200.0;
  robust.k_p = 60.0;
  auto r = on_drawn_machine(wp_m, SpeedProfile::sharp_corner, robust);
  ASSERT_TRUE(r.ok()) << r.error().to_string();
  EXPECT_TRUE(r->finished);
  EXPECT_LT(r->limited_fraction, 0.01);
  EXPECT_LT(r->max_cross_m, 0.5e-3);
  EXPECT_GT(r->max_cross_m, 10.0 * 3.61e-6);  // and well above the controller's own model's 3.6 um
}

// The arc-length variant against Eq. 67 on a part neither was tuned on (the corpus cube, one
// layer: four 90-degree corners between 20 mm edges), on a drawn machine with its drive limits:
// faster, and no worse on max and IAE. a1/a2 as bench_maneuver's table C tuned them on the
// generated parts.
TEST(OffNominalPlant, TheArcVariantBeatsEq67OnAHeldOutPartWithLimits) {
  GcodePathOptions gp;
  gp.layers = 1;
  gp.feature = "External perimeter";
  auto wp = extrusion_path_from_gcode_file(
      std::string(FEEDLOOP_SHARED_DIR) + "/gcode/cube20_cartesian.gcode", gp);
  if (!wp.ok()) GTEST_SKIP() << wp.error().to_string();
  std::vector<Vec3> wp_m;
  for (const Vec3& q : *wp) wp_m.push_back(q * 1e-3);
  ManeuverGains robust;
  robust.k_d = 200.0;
  robust.k_p = 60.0;
  auto e67 = on_drawn_machine(wp_m, SpeedProfile::sharp_corner, robust);
  SpeedParams sp;
  sp.a1_m = 0.03e-3;
  sp.a2_m = 0.0025e-3;
  ManeuverGains arc_gains = robust;
  arc_gains.mu *= 4.86e-3 * 4.86e-3;  // Table II's mu x the training parts' mean segment squared
  auto arc = on_drawn_machine(wp_m, SpeedProfile::sharp_corner_arc, arc_gains, sp);
  ASSERT_TRUE(e67.ok() && arc.ok());
  ASSERT_TRUE(e67->finished && arc->finished);
  EXPECT_LT(arc->total_time_s, 0.8 * e67->total_time_s);
  EXPECT_LE(arc->max_cross_m, 1.05 * e67->max_cross_m);
  EXPECT_LT(arc->iae_cross_m_s, e67->iae_cross_m_s);
  EXPECT_LT(arc->limited_fraction, 0.01);
}

}  // namespace
}  // namespace feedloop::maneuver
