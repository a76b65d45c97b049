// Temperature sensors behind an ADC: a thermistor (or PT1000) to ground with a pull-up resistor
// to the ADC's reference, read as the fraction adc = R / (R + R_pullup) in [0, 1].
// Thermistors follow Klipper's approach (klippy/extras/thermistor.py): a Steinhart-Hart fit
// 1/T = c0 + c1 ln R + c3 (ln R)^3 through three (temperature, resistance) points of the
// datasheet, or the beta form 1/T = 1/T0 + ln(R/R0)/beta. The built-in types are the three-point
// sets Klipper ships for the Semitec 104GT-2 and the EPCOS 100K B57560G104F; the PT1000 uses the
// Callendar-Van Dusen equation (IEC 60751, T >= 0 C). Pure functions; no allocation.
#pragma once

#include <optional>
#include <string_view>

namespace feedloop::thermal {

inline constexpr double kKelvinOffset = 273.15;

enum class SensorKind { kSteinhartHart, kPt1000 };

struct SensorParams {
  SensorKind kind = SensorKind::kSteinhartHart;
  // Steinhart-Hart coefficients (1/K): 1/T = c0 + c1 ln R + c3 (ln R)^3, T in kelvin.
  double c0 = 0.0, c1 = 0.0, c3 = 0.0;
  double pt_r0_ohm = 1000.0;   // PT1000: resistance at 0 C
  double pullup_ohm = 4700.0;  // the divider's pull-up
};

// Three-point Steinhart-Hart fit (Klipper's "temperature1/resistance1 ... 3").
std::optional<SensorParams> steinhart_hart(double t1_c, double r1_ohm, double t2_c, double r2_ohm,
                                           double t3_c, double r3_ohm, double pullup_ohm = 4700.0);
// Beta form (c3 = 0): resistance r0_ohm at t0_c.
std::optional<SensorParams> beta_thermistor(double t0_c, double r0_ohm, double beta,
                                            double pullup_ohm = 4700.0);
// Built-in types by name: "Semitec 104GT-2", "EPCOS 100K B57560G104F", "PT1000" (Klipper's names).
std::optional<SensorParams> builtin_sensor(std::string_view name, double pullup_ohm = 4700.0);

double resistance_at(const SensorParams& p, double temp_c);      // ohm
double temp_at_resistance(const SensorParams& p, double r_ohm);  // C
// ADC fraction <-> temperature through the divider. adc <= 0 (a short) reads as +inf; adc >= 1
// (an open sensor) as -inf: the protection's max/min temperature catches both.
double adc_at(const SensorParams& p, double temp_c);
double temp_at_adc(const SensorParams& p, double adc);

}  // namespace feedloop::thermal
