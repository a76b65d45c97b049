// The carriage experiment of Sect. IV-A measured in the time domain (multisine through step
// pulses, H1 from ident/frf.hpp) instead of the small-signal FRF: the two agree, and the carriage
// sub-model identified from the H1 estimates matches the simulator.
#include <cmath>
#include <cstdio>

#include <gtest/gtest.h>

#include "ident/delta/delta_ident.hpp"
#include "sim/experiments/delta_measurements.hpp"

namespace feedloop::ident::delta {
namespace {

double rel_err(double got, double want) { return std::abs(got / want - 1.0); }

TEST(DeltaIdentSweep, CarriageFromH1OfAMultisine) {
  const sim::DeltaPlantParams truth;
  auto small_signal = sim::simulate_measurements(truth, MeasurementPlan{});
  ASSERT_TRUE(small_signal.ok()) << small_signal.error().message;
  auto h = sim::measure_carriage_h1(truth, MeasurementPlan{}, false);
  auto h_added = sim::measure_carriage_h1(truth, MeasurementPlan{}, true);
  ASSERT_TRUE(h.ok()) << h.error().message;
  ASSERT_TRUE(h_added.ok()) << h_added.error().message;
  double worst = 0.0, sum = 0.0;
  for (size_t k = 0; k < h->size(); ++k) {
    const double e = std::abs((*h)[k] / small_signal->carriage[k] - 1.0);
    worst = std::max(worst, e);
    sum += e * e;
  }
  const double rms = std::sqrt(sum / static_cast<double>(h->size()));
  std::printf("H1 vs small-signal carriage FRF: rms %.2e, worst %.2e (relative)\n", rms, worst);
  EXPECT_LT(rms, 0.01);

  DeltaMeasurements meas = *small_signal;
  meas.carriage = *h;
  meas.carriage_added = *h_added;
  auto c = identify_carriage(meas);
  ASSERT_TRUE(c.ok()) << c.error().message;
  const model::DeltaParams& t = truth.model;
  std::printf("from H1: m_c %.4f k %.4g c %.3f b %.3f d0 %.4g d1 %.2f d2 %.2f\n", c->m_c_kg, c->k_n_m, c->c_n_s_m,
              c->b_n_s_m, c->d0_per_s2, c->d1_per_s, c->d2_per_s);
  EXPECT_LT(rel_err(c->m_c_kg, t.m_c_kg), 0.02);
  EXPECT_LT(rel_err(c->k_n_m, t.k_n_m), 0.02);
  EXPECT_LT(rel_err(c->c_n_s_m + c->b_n_s_m, t.c_n_s_m + t.b_n_s_m), 0.05);
  EXPECT_LT(rel_err(c->d0_per_s2, t.d0_per_s2), 0.02);
  EXPECT_LT(rel_err(c->d1_per_s, t.d1_per_s), 0.02);
  EXPECT_LT(rel_err(c->d2_per_s, t.d2_per_s), 0.05);
}

}  // namespace
}  // namespace feedloop::ident::delta
