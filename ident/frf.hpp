// Frequency response estimation from traces: the H1 estimator with Welch averaging, and the
// coherence, evaluated on the papers' frequency grid (model/frequency_grid.hpp: the delta paper's
// 2-125 Hz in 0.5 Hz steps by default).
//
//   segments of `segment_s` seconds, `overlap` fraction overlapping, each linearly detrended and
//   windowed (Hann by default), FFT (FFTW r2c);
//   S_uu = sum |U|^2,  S_yy = sum |Y|^2,  S_uy = sum conj(U) Y        (sums over the segments)
//   H1 = S_uy / S_uu,  coherence gamma^2 = |S_uy|^2 / (S_uu S_yy)
// H1 is unbiased by noise on the output (the encoder); gamma^2 falls below 1 where output noise
// or a nonlinearity is not explained linearly by the input. The spectra are interpolated linearly
// between FFT bins onto the grid (with the default segment length, 1 / grid step, and an integer
// number of samples per segment, the grid points are bins and nothing is interpolated).
//
// The model side of the comparison: foh_frequency_response() is the FRF from the sampled input to
// the sampled output of a continuous model driven by the linear interpolation of the input
// samples (a first-order hold, what the step driver does: the steps of one sample period are spread
// over it), z = e^{j 2 pi f T}. At 1 kHz it differs from G(j 2 pi f) by up to a few % near 125 Hz.
#pragma once

#include <complex>
#include <string>
#include <vector>

#include "core/result.hpp"
#include "ident/axis_model.hpp"
#include "model/frequency_grid.hpp"
#include "model/lti.hpp"

namespace feedloop::ident {

enum class FrfWindow { kHann, kRectangular };

struct WelchOptions {
  double segment_s = 0.0;  // segment length; 0: 1 / grid step (2 s for the 0.5 Hz grid)
  double overlap = 0.5;    // fraction of a segment shared with the next, in [0, 0.95]
  FrfWindow window = FrfWindow::kHann;
  bool detrend = true;     // remove each segment's least-squares line (position traces drift)
};

struct FrfEstimate {
  std::vector<double> freq_hz;
  std::vector<std::complex<double>> h1;  // output / input (mm/mm for position traces)
  std::vector<double> coherence;         // gamma^2 in [0, 1]
  std::vector<double> input_psd;         // one-sided, units^2/Hz (window-corrected)
  std::vector<double> output_psd;
  int segments = 0;
  double segment_s = 0.0;
};

// H1 estimate of y against u (same length, sampled at sample_rate_hz) on `grid`.
// Errors: lengths differ, non-positive rate, bad options or grid, a grid above Nyquist, a trace
// shorter than one segment (the message says how many samples are needed).
Result<FrfEstimate> estimate_frf_h1(const std::vector<double>& u, const std::vector<double>& y,
                                    double sample_rate_hz, const model::FrequencyGrid& grid = {},
                                    const WelchOptions& options = {});

// Sampled-input to sampled-output FRF of a single-input single-output state space driven through
// a first-order hold at period_s (exact discretisation by the matrix exponential), at each grid
// point. Error when the system is not SISO or not finite.
Result<std::vector<std::complex<double>>> foh_frequency_response(const model::StateSpace& sys, double period_s,
                                                                  const model::FrequencyGrid& grid);

// The identification model's FRF on the same footing as H1 of a trace sampled at period_s: the
// first-order-hold response of axis_state_space(m), times the scale error and the delay
// e^{-j w d} when those effects are on (the other nonlinear effects have no FRF and are left out).
Result<std::vector<std::complex<double>>> axis_model_frf(const AxisModel& m, double period_s,
                                                          const model::FrequencyGrid& grid);

// The FRF estimate as CSV: freq_hz,mag,phase_deg,re,im,coherence (plus model columns
// model_mag,model_phase_deg when `model` has one value per grid point).
std::string format_frf_csv(const FrfEstimate& est, const std::vector<std::complex<double>>& model = {});
Status write_frf_csv(const std::string& path, const FrfEstimate& est,
                     const std::vector<std::complex<double>>& model = {});

}  // namespace feedloop::ident
