#include "thermal/sensor.hpp"

#include <cmath>
#include <limits>

namespace feedloop::thermal {

std::optional<SensorParams> steinhart_hart(double t1_c, double r1_ohm, double t2_c, double r2_ohm,
                                           double t3_c, double r3_ohm, double pullup_ohm) {
  // Klipper's thermistor.py solves the same 3x3 system in closed form.
  if (!(r1_ohm > 0 && r2_ohm > 0 && r3_ohm > 0 && pullup_ohm > 0)) return std::nullopt;
  const double inv1 = 1.0 / (t1_c + kKelvinOffset), inv2 = 1.0 / (t2_c + kKelvinOffset),
               inv3 = 1.0 / (t3_c + kKelvinOffset);
  const double ln1 = std::log(r1_ohm), ln2 = std::log(r2_ohm), ln3 = std::log(r3_ohm);
  const double ln1_3 = ln1 * ln1 * ln1, ln2_3 = ln2 * ln2 * ln2, ln3_3 = ln3 * ln3 * ln3;
  const double inv12 = inv1 - inv2, inv13 = inv1 - inv3;
  const double ln12 = ln1 - ln2, ln13 = ln1 - ln3;
  const double den = (ln1_3 - ln3_3) - ln13 * (ln1_3 - ln2_3) / ln12;
  if (!(std::fabs(ln12) > 1e-12) || !(std::fabs(den) > 1e-18)) return std::nullopt;
  SensorParams p;
  p.pullup_ohm = pullup_ohm;
  p.c3 = (inv13 - inv12 * ln13 / ln12) / den;
  if (p.c3 <= 0) {  // Klipper: fall back to the beta form from points 1 and 3
    return beta_thermistor(t1_c, r1_ohm, std::log(r1_ohm / r3_ohm) / inv13, pullup_ohm);
  }
  p.c1 = (inv12 - p.c3 * (ln1_3 - ln2_3)) / ln12;
  p.c0 = inv1 - p.c1 * ln1 - p.c3 * ln1_3;
  // The fit must be monotonic (temperature falls as resistance rises) over 1 ohm .. 10 Mohm.
  if (!(p.c1 > 0)) return std::nullopt;
  return p;
}

std::optional<SensorParams> beta_thermistor(double t0_c, double r0_ohm, double beta,
                                            double pullup_ohm) {
  if (!(r0_ohm > 0 && beta > 0 && pullup_ohm > 0 && t0_c > -kKelvinOffset)) return std::nullopt;
  SensorParams p;
  p.pullup_ohm = pullup_ohm;
  p.c1 = 1.0 / beta;
  p.c0 = 1.0 / (t0_c + kKelvinOffset) - p.c1 * std::log(r0_ohm);
  p.c3 = 0.0;
  return p;
}

std::optional<SensorParams> builtin_sensor(std::string_view name, double pullup_ohm) {
  // Klipper's klippy/extras/temperature_sensors.cfg / thermistor.py defaults.
  if (name == "Semitec 104GT-2")
    return steinhart_hart(20, 126800, 150, 1360, 300, 80.65, pullup_ohm);
  if (name == "EPCOS 100K B57560G104F")
    return steinhart_hart(25, 100000, 150, 1641.9, 250, 226.15, pullup_ohm);
  if (name == "PT1000") {
    SensorParams p;
    p.kind = SensorKind::kPt1000;
    p.pullup_ohm = pullup_ohm;
    if (!(pullup_ohm > 0)) return std::nullopt;
    return p;
  }
  return std::nullopt;
}

namespace {
// Callendar-Van Dusen (T >= 0 C; extended below 0 with the same quadratic, accurate to ~0.5 C at
// -40).
constexpr double kCvdA = 3.9083e-3, kCvdB = -5.775e-7;
}  // namespace

double resistance_at(const SensorParams& p, double temp_c) {
  if (p.kind == SensorKind::kPt1000)
    return p.pt_r0_ohm * (1.0 + kCvdA * temp_c + kCvdB * temp_c * temp_c);
  // Invert 1/T = c0 + c1 x + c3 x^3 for x = ln R (Cardano when c3 > 0).
  const double y = 1.0 / (temp_c + kKelvinOffset) - p.c0;
  double x;
  if (p.c3 == 0.0) {
    x = y / p.c1;
  } else {
    const double q = -y / p.c3, pp = p.c1 / p.c3;  // x^3 + pp x + q = 0
    const double disc = std::sqrt(q * q / 4.0 + pp * pp * pp / 27.0);
    x = std::cbrt(-q / 2.0 + disc) + std::cbrt(-q / 2.0 - disc);
  }
  return std::exp(x);
}

double temp_at_resistance(const SensorParams& p, double r_ohm) {
  if (!(r_ohm > 0)) return std::numeric_limits<double>::infinity();
  if (p.kind == SensorKind::kPt1000) {
    const double ratio = r_ohm / p.pt_r0_ohm;
    const double disc = kCvdA * kCvdA - 4.0 * kCvdB * (1.0 - ratio);
    if (disc < 0) return std::numeric_limits<double>::infinity();
    return (-kCvdA + std::sqrt(disc)) / (2.0 * kCvdB);
  }
  const double ln = std::log(r_ohm);
  const double inv = p.c0 + p.c1 * ln + p.c3 * ln * ln * ln;
  if (!(inv > 0)) return std::numeric_limits<double>::infinity();
  return 1.0 / inv - kKelvinOffset;
}

double adc_at(const SensorParams& p, double temp_c) {
  const double r = resistance_at(p, temp_c);
  return r / (r + p.pullup_ohm);
}

double temp_at_adc(const SensorParams& p, double adc) {
  if (!(adc > 0.0)) return std::numeric_limits<double>::infinity();  // short (or NaN)
  if (adc >= 1.0) return -std::numeric_limits<double>::infinity();   // open
  return temp_at_resistance(p, p.pullup_ohm * adc / (1.0 - adc));
}

}  // namespace feedloop::thermal
