// Sine-dwell frequency response of a simulated axis driven through real step pulses: commands
// u(t) = center + A sin(2 pi f t), waits settle periods, then correlates the measured output and
// the commanded (step-quantised) position with e^{-j w t} over whole periods. The ratio is the
// FRF at f, including every nonlinearity the small-signal linearisation leaves out.
#pragma once

#include <complex>
#include <functional>

#include "drivers/device/motor_port.hpp"

namespace feedloop::sim {

struct SineDwellSpec {
  double freq_hz = 10.0;
  double amplitude_mm = 0.05;
  double center_mm = 0.0;      // the port's commanded position at t0 (its step counter is zero there)
  int settle_periods = 10;
  int measure_periods = 10;
  int samples_per_period = 256;
};

// output_at(t_s) must advance the plant to t_s and return the output in mm. Returns output/input.
std::complex<double> sine_dwell(device::MotorPort& port, double mm_per_step, double t0_s,
                                const SineDwellSpec& spec,
                                const std::function<double(double t_s)>& output_at);

}  // namespace feedloop::sim
