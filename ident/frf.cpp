// H1 frequency response estimation with Welch averaging (see frf.hpp).
#include "ident/frf.hpp"

#include <fftw3.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <mutex>

#include <Eigen/Dense>
#include <unsupported/Eigen/MatrixFunctions>

#include "model/lead_lag.hpp"

namespace feedloop::ident {
namespace {

constexpr double kPi = 3.14159265358979323846;

// FFTW's planner is not thread-safe; plans are made and destroyed under this lock (executing a
// plan with the new-array interface is thread-safe).
std::mutex& fftw_planner_mutex() {
  static std::mutex m;
  return m;
}

// A real-to-complex plan of size n with its own aligned buffers.
class R2cPlan {
 public:
  explicit R2cPlan(int n) {
    std::lock_guard<std::mutex> lock(fftw_planner_mutex());
    in_ = fftw_alloc_real(static_cast<size_t>(n));
    out_ = fftw_alloc_complex(static_cast<size_t>(n / 2 + 1));
    plan_ = fftw_plan_dft_r2c_1d(n, in_, out_, FFTW_ESTIMATE);
  }
  ~R2cPlan() {
    std::lock_guard<std::mutex> lock(fftw_planner_mutex());
    if (plan_ != nullptr) fftw_destroy_plan(plan_);
    fftw_free(in_);
    fftw_free(out_);
  }
  R2cPlan(const R2cPlan&) = delete;
  R2cPlan& operator=(const R2cPlan&) = delete;

  bool ok() const { return plan_ != nullptr && in_ != nullptr && out_ != nullptr; }
  double* in() { return in_; }
  std::complex<double> out(int k) const { return {out_[k][0], out_[k][1]}; }
  void execute() { fftw_execute(plan_); }

 private:
  double* in_ = nullptr;
  fftw_complex* out_ = nullptr;
  fftw_plan plan_ = nullptr;
};

// Copies x[begin, begin + n) into dst, minus its least-squares line when detrending, times w.
void prepare_segment(const std::vector<double>& x, size_t begin, int n, bool detrend, const std::vector<double>& w,
                     double* dst) {
  double a = 0.0, b = 0.0;  // x ~ a + b (i - c)
  const double c = 0.5 * (n - 1);
  if (detrend) {
    double sx = 0.0, sxt = 0.0, stt = 0.0;
    for (int i = 0; i < n; ++i) {
      const double t = i - c;
      const double v = x[begin + static_cast<size_t>(i)];
      sx += v;
      sxt += v * t;
      stt += t * t;
    }
    a = sx / n;
    b = stt > 0.0 ? sxt / stt : 0.0;
  }
  for (int i = 0; i < n; ++i) dst[i] = (x[begin + static_cast<size_t>(i)] - a - b * (i - c)) * w[static_cast<size_t>(i)];
}

std::string fmt(double v, const char* f = "%.6g") {
  char buf[64];
  std::snprintf(buf, sizeof buf, f, v);
  return buf;
}

}  // namespace

Result<FrfEstimate> estimate_frf_h1(const std::vector<double>& u, const std::vector<double>& y, double sample_rate_hz,
                                    const model::FrequencyGrid& grid, const WelchOptions& options) {
  if (u.size() != y.size())
    return Error{"FRF: input and output have different lengths (" + std::to_string(u.size()) + " and " +
                     std::to_string(y.size()) + " samples)",
                 {}};
  if (!(sample_rate_hz > 0.0) || !std::isfinite(sample_rate_hz)) return Error{"FRF: sample rate must be > 0", {}};
  if (auto s = grid.validate(); !s) return Error{"FRF: " + s.error().message, {}};
  if (!(options.overlap >= 0.0 && options.overlap <= 0.95)) return Error{"FRF: overlap must be in [0, 0.95]", {}};
  if (grid.at_hz(grid.size() - 1) > 0.5 * sample_rate_hz)
    return Error{"FRF: grid reaches " + fmt(grid.at_hz(grid.size() - 1)) + " Hz, above the Nyquist frequency " +
                     fmt(0.5 * sample_rate_hz) + " Hz",
                 {}};
  const double segment_s = options.segment_s > 0.0 ? options.segment_s : 1.0 / grid.step_hz;
  const double n_real = std::round(segment_s * sample_rate_hz);
  if (!(n_real >= 8.0) || n_real > 1e8) return Error{"FRF: segment must hold 8 to 1e8 samples", {}};
  const int n = static_cast<int>(n_real);
  if (u.size() < static_cast<size_t>(n))
    return Error{"FRF: trace has " + std::to_string(u.size()) + " samples, one " + fmt(segment_s) +
                     " s segment needs " + std::to_string(n),
                 {}};
  for (size_t k = 0; k < u.size(); ++k)
    if (!std::isfinite(u[k]) || !std::isfinite(y[k]))
      return Error{"FRF: non-finite sample at index " + std::to_string(k), {}};

  std::vector<double> w(static_cast<size_t>(n), 1.0);
  if (options.window == FrfWindow::kHann)
    for (int i = 0; i < n; ++i) w[static_cast<size_t>(i)] = 0.5 - 0.5 * std::cos(2.0 * kPi * i / n);  // periodic Hann
  double w2 = 0.0;
  for (double v : w) w2 += v * v;

  const int bins = n / 2 + 1;
  std::vector<double> suu(static_cast<size_t>(bins), 0.0), syy(static_cast<size_t>(bins), 0.0);
  std::vector<std::complex<double>> suy(static_cast<size_t>(bins), 0.0);
  R2cPlan pu(n), py(n);
  if (!pu.ok() || !py.ok()) return Error{"FRF: FFTW could not plan a transform of " + std::to_string(n), {}};
  const auto hop = static_cast<size_t>(std::max(1.0, std::round(n * (1.0 - options.overlap))));
  int segments = 0;
  for (size_t begin = 0; begin + static_cast<size_t>(n) <= u.size(); begin += hop) {
    prepare_segment(u, begin, n, options.detrend, w, pu.in());
    prepare_segment(y, begin, n, options.detrend, w, py.in());
    pu.execute();
    py.execute();
    for (int k = 0; k < bins; ++k) {
      const std::complex<double> U = pu.out(k), Y = py.out(k);
      suu[static_cast<size_t>(k)] += std::norm(U);
      syy[static_cast<size_t>(k)] += std::norm(Y);
      suy[static_cast<size_t>(k)] += std::conj(U) * Y;
    }
    ++segments;
  }

  FrfEstimate est;
  est.segments = segments;
  est.segment_s = n / sample_rate_hz;
  const double df = sample_rate_hz / n;
  const double psd_scale = 2.0 / (sample_rate_hz * w2 * segments);  // one-sided PSD
  const int m = grid.size();
  est.freq_hz.resize(static_cast<size_t>(m));
  est.h1.resize(static_cast<size_t>(m));
  est.coherence.resize(static_cast<size_t>(m));
  est.input_psd.resize(static_cast<size_t>(m));
  est.output_psd.resize(static_cast<size_t>(m));
  for (int g = 0; g < m; ++g) {
    const double f = grid.at_hz(g);
    const double pos = f / df;
    auto i0 = static_cast<int>(std::floor(pos + 1e-9));
    double frac = pos - i0;
    if (frac < 1e-9) frac = 0.0;
    i0 = std::min(i0, bins - 1);
    const int i1 = std::min(i0 + 1, bins - 1);
    const auto at = [&](const auto& v) { return v[static_cast<size_t>(i0)] * (1.0 - frac) + v[static_cast<size_t>(i1)] * frac; };
    const double a = at(suu), b = at(syy);
    const std::complex<double> c = at(suy);
    const auto gi = static_cast<size_t>(g);
    est.freq_hz[gi] = f;
    est.h1[gi] = a > 0.0 ? c / a : std::complex<double>(std::nan(""), std::nan(""));
    est.coherence[gi] = a > 0.0 && b > 0.0 ? std::min(1.0, std::norm(c) / (a * b)) : 0.0;
    est.input_psd[gi] = a * psd_scale;
    est.output_psd[gi] = b * psd_scale;
  }
  return est;
}

Result<std::vector<std::complex<double>>> foh_frequency_response(const model::StateSpace& sys, double period_s,
                                                                  const model::FrequencyGrid& grid) {
  if (auto s = model::check_dimensions(sys); !s) return s.error();
  if (sys.inputs() != 1 || sys.outputs() != 1) return Error{"FOH FRF: the system must have one input and one output", {}};
  if (!(period_s > 0.0)) return Error{"FOH FRF: sample period must be > 0", {}};
  if (auto s = grid.validate(); !s) return s.error();
  const int n = sys.states();
  // exp([[A h, B h, 0], [0, 0, 1], [0, 0, 0]]) = [[Ad, G0, G1], ...]: x+ = Ad x + G0 u_k + G1 (u_{k+1} - u_k).
  Eigen::MatrixXd M = Eigen::MatrixXd::Zero(n + 2, n + 2);
  M.topLeftCorner(n, n) = sys.A * period_s;
  M.block(0, n, n, 1) = sys.B * period_s;
  M(n, n + 1) = 1.0;
  const Eigen::MatrixXd E = M.exp();
  if (!E.allFinite()) return Error{"FOH FRF: discretisation failed (non-finite matrix exponential)", {}};
  const Eigen::MatrixXcd Ad = E.topLeftCorner(n, n).cast<std::complex<double>>();
  const Eigen::VectorXcd g0 = E.block(0, n, n, 1).cast<std::complex<double>>();
  const Eigen::VectorXcd g1 = E.block(0, n + 1, n, 1).cast<std::complex<double>>();
  const Eigen::RowVectorXcd C = sys.C.cast<std::complex<double>>();
  const std::complex<double> D = sys.D(0, 0);
  std::vector<std::complex<double>> h(static_cast<size_t>(grid.size()));
  for (int g = 0; g < grid.size(); ++g) {
    const std::complex<double> z = std::polar(1.0, 2.0 * kPi * grid.at_hz(g) * period_s);
    const Eigen::MatrixXcd zI_A = z * Eigen::MatrixXcd::Identity(n, n) - Ad;
    const Eigen::VectorXcd x = zI_A.partialPivLu().solve(g0 + g1 * (z - 1.0));
    h[static_cast<size_t>(g)] = (C * x)(0, 0) + D;
  }
  return h;
}

Result<std::vector<std::complex<double>>> axis_model_frf(const AxisModel& m, double period_s,
                                                          const model::FrequencyGrid& grid) {
  auto h = foh_frequency_response(axis_state_space(m), period_s, grid);
  if (!h) return h;
  const double scale = m.has(Effect::kScaleError) ? m.scale : 1.0;
  const double delay_s = m.has(Effect::kTimeDelay) ? m.delay_ms * 1e-3 : 0.0;
  // The field lag's (1 + T s) / (1 + tau s), as simulate_axis has it.
  const double tau = m.field_lag_ms * 1e-3, T = m.field_lag_ms > 0.0 ? m.c1_n_s_m / m.k1_n_m : 0.0;
  for (int g = 0; g < grid.size(); ++g) {
    const std::complex<double> f =
        tau > 0.0 ? model::tustin_lead_lag_response(T, tau, period_s, grid.at_hz(g)) : 1.0;
    h.value()[static_cast<size_t>(g)] *=
        f * scale * std::polar(1.0, -2.0 * kPi * grid.at_hz(g) * delay_s);
  }
  return h;
}

std::string format_frf_csv(const FrfEstimate& est, const std::vector<std::complex<double>>& model) {
  const bool with_model = model.size() == est.freq_hz.size() && !model.empty();
  std::string s = "freq_hz,mag,phase_deg,re,im,coherence";
  if (with_model) s += ",model_mag,model_phase_deg";
  s += "\n";
  for (size_t i = 0; i < est.freq_hz.size(); ++i) {
    const auto h = est.h1[i];
    s += fmt(est.freq_hz[i], "%.4f") + "," + fmt(std::abs(h), "%.8g") + "," + fmt(std::arg(h) * 180.0 / kPi, "%.5f") +
         "," + fmt(h.real(), "%.8g") + "," + fmt(h.imag(), "%.8g") + "," + fmt(est.coherence[i], "%.6f");
    if (with_model)
      s += "," + fmt(std::abs(model[i]), "%.8g") + "," + fmt(std::arg(model[i]) * 180.0 / kPi, "%.5f");
    s += "\n";
  }
  return s;
}

Status write_frf_csv(const std::string& path, const FrfEstimate& est, const std::vector<std::complex<double>>& model) {
  std::ofstream f(path, std::ios::binary);
  if (!f) return Error{"cannot write file", SourceLocation{path, 0, 0}};
  f << format_frf_csv(est, model);
  if (!f) return Error{"write failed", SourceLocation{path, 0, 0}};
  return Status::Ok();
}

}  // namespace feedloop::ident
