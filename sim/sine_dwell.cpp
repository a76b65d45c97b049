// Sine-dwell FRF estimation (see sine_dwell.hpp).
#include "sim/sine_dwell.hpp"

#include <cmath>

#include "sim/step_driver.hpp"

namespace feedloop::sim {

std::complex<double> sine_dwell(device::MotorPort& port, double mm_per_step, double t0_s,
                                const SineDwellSpec& spec,
                                const std::function<double(double t_s)>& output_at) {
  constexpr double kTwoPi = 6.283185307179586;
  StepDriver drive(port, mm_per_step, spec.center_mm, t0_s);
  const double period_s = 1.0 / spec.freq_hz;
  const double dt = period_s / spec.samples_per_period;
  std::complex<double> in_acc = 0.0, out_acc = 0.0;
  const int total = (spec.settle_periods + spec.measure_periods) * spec.samples_per_period;
  for (int k = 1; k <= total; ++k) {  // the last sample closes the last interval
    const double tau = k * dt;  // time since t0
    const double t = t0_s + tau;
    drive.update(t, spec.center_mm + spec.amplitude_mm * std::sin(kTwoPi * spec.freq_hz * tau));
    const double y = output_at(t);
    if (k >= spec.settle_periods * spec.samples_per_period && k < total) {
      // The commanded staircase is constant on [t_k, t_k+1) (steps land on sample times), so it
      // is integrated exactly; the smooth output is sampled.
      const double w = kTwoPi * spec.freq_hz;
      const std::complex<double> e0 = std::polar(1.0, -w * tau);
      const std::complex<double> e1 = std::polar(1.0, -w * (tau + dt));
      in_acc += (drive.commanded_mm() - spec.center_mm) * (e0 - e1) / std::complex<double>(0.0, w);
      out_acc += (y - spec.center_mm) * e0 * dt;
    }
  }
  return out_acc / in_acc;
}

}  // namespace feedloop::sim
