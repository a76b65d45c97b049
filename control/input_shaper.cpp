// Impulse sets (Klipper's ZV / MZV / EI), the residual-vibration formula, and the centred FIR that
// applies them to the sampled reference with linear interpolation (see input_shaper.hpp).
#include "control/input_shaper.hpp"

#include <algorithm>  // std::max
#include <cmath>      // std::sqrt, std::exp, std::ceil, std::floor, std::cos, std::sin
#include <numbers>    // std::numbers::pi
#include <string>

namespace feedloop::control {
namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kEiVibrationTolerance = 0.05;  // V_tol of EI (Klipper: 1 / SHAPER_VIBRATION_REDUCTION)
constexpr double kTimeEps = 1e-9;               // in periods: an impulse this close to a sample is on it
constexpr int kMaxRingSamples = 1 << 16;        // a shaper longer than this many periods is a config error

Error shaper_error(const std::string& what) { return Error{"input shaper: " + what, {}}; }

// Evaluates c0 + c1 zeta + c2 zeta^2 + c3 zeta^3 where each c_j = p_j + q_j V_tol (EI fits).
double fit(const std::array<std::array<double, 2>, 4>& c, double zeta, double v_tol) {
  double r = 0.0;
  for (int j = 3; j >= 0; --j) r = r * zeta + (c[j][0] + c[j][1] * v_tol);
  return r;
}

Impulses normalised(Impulses s) {
  double sum = 0.0;
  for (int i = 0; i < s.n; ++i) sum += s.a[i];
  for (int i = 0; i < s.n; ++i) s.a[i] /= sum;
  return s;
}

}  // namespace

const char* shaper_name(ShaperType type) {
  switch (type) {
    case ShaperType::zv: return "zv";
    case ShaperType::mzv: return "mzv";
    case ShaperType::ei: return "ei";
  }
  return "?";
}

Result<Impulses> make_impulses(ShaperType type, double freq_hz, double damping) {
  if (!std::isfinite(freq_hz) || freq_hz <= 0.0)
    return shaper_error(std::string(shaper_name(type)) + ": freq_hz must be > 0");
  if (!std::isfinite(damping) || damping < 0.0 || damping >= 1.0)
    return shaper_error(std::string(shaper_name(type)) + ": damping must be in [0, 1)");
  const double df = std::sqrt(1.0 - damping * damping);
  const double t_d_s = 1.0 / (freq_hz * df);  // damped period of the mode
  Impulses s;
  switch (type) {
    case ShaperType::zv: {
      // Zero vibration: two impulses half a damped period apart, the second scaled by the decay.
      const double k = std::exp(-damping * kPi / df);
      s.n = 2;
      s.a = {1.0, k};
      s.t_s = {0.0, 0.5 * t_d_s};
      break;
    }
    case ShaperType::mzv: {
      // Three equal spacings of 3/8 damped period; undamped amplitudes [a, b, a] with
      // b / (2a) = cos(3 pi / 4) magnitude so that the mode's phasors cancel: a = 1 - 1/sqrt2.
      const double k = std::exp(-0.75 * damping * kPi / df);
      const double a1 = 1.0 - 1.0 / std::sqrt(2.0);
      s.n = 3;
      s.a = {a1, (std::sqrt(2.0) - 1.0) * k, a1 * k * k};
      s.t_s = {0.0, 0.375 * t_d_s, 0.75 * t_d_s};
      break;
    }
    case ShaperType::ei: {
      if (damping > 0.4)
        return shaper_error("ei: damping must be <= 0.4 (the range of the EI fit)");
      // Extra-insensitive shaper, curve fits in zeta (coefficients {p, q}: c = p + q V_tol).
      static constexpr std::array<std::array<double, 2>, 4> kA1 = {
          {{0.24968, 0.24961}, {0.80008, 1.23328}, {0.49599, 3.17316}, {0.0, 0.0}}};
      static constexpr std::array<std::array<double, 2>, 4> kA3 = {
          {{0.25149, 0.21474}, {-0.83249, 1.41498}, {0.85181, -4.90094}, {0.0, 0.0}}};
      // t2 / t_d = 0.4999 + V (0.46159 + 8.57843 V) zeta + V (4.26169 - 108.644 V) zeta^2
      //            + V (1.75601 + 336.989 V) zeta^3
      const double v = kEiVibrationTolerance;
      constexpr double vt = kEiVibrationTolerance;
      static constexpr std::array<std::array<double, 2>, 4> kT2 = {{{0.4999, 0.0},
                                                                   {0.0, 0.46159 + 8.57843 * vt},
                                                                   {0.0, 4.26169 - 108.644 * vt},
                                                                   {0.0, 1.75601 + 336.989 * vt}}};
      const double t2 = fit(kT2, damping, v);
      const double a1 = fit(kA1, damping, v);
      const double a3 = fit(kA3, damping, v);
      s.n = 3;
      s.a = {a1, 1.0 - a1 - a3, a3};
      s.t_s = {0.0, t2 * t_d_s, t_d_s};
      break;
    }
  }
  return normalised(s);
}

double centre_time_s(const Impulses& s) {
  double sum_a = 0.0, sum_at = 0.0;
  for (int i = 0; i < s.n; ++i) {
    sum_a += s.a[i];
    sum_at += s.a[i] * s.t_s[i];
  }
  return sum_a != 0.0 ? sum_at / sum_a : 0.0;
}

double residual_vibration(const Impulses& s, double freq_hz, double damping) {
  if (s.n <= 0) return 1.0;
  const double w = 2.0 * kPi * freq_hz;
  const double w_d = w * std::sqrt(1.0 - damping * damping);
  const double t_n = s.t_s[s.n - 1];
  double c = 0.0, sn = 0.0, sum_a = 0.0;
  for (int i = 0; i < s.n; ++i) {
    // exp(zeta w (t_i - t_N)) keeps the terms bounded (the exp(-zeta w t_N) factor moved inside).
    const double decay = std::exp(damping * w * (s.t_s[i] - t_n));
    c += s.a[i] * decay * std::cos(w_d * s.t_s[i]);
    sn += s.a[i] * decay * std::sin(w_d * s.t_s[i]);
    sum_a += s.a[i];
  }
  return std::sqrt(c * c + sn * sn) / sum_a;
}

Status InputShaper::configure(const InputShaperSetup& setup) {
  const double period_s = setup.period_s;
  if (!std::isfinite(period_s) || period_s <= 0.0) return shaper_error("period_s must be > 0");
  cartesian_ = setup.linear_map.has_value();
  if (cartesian_) map_ = *setup.linear_map;
  // P = ceil(t_c / T) over all shapers: every axis then reads its own t_c ahead of t_k.
  preview_ = 0;
  for (const auto& s : setup.shapers) {
    if (!s) continue;
    if (s->n < 1 || s->n > kMaxImpulses) return shaper_error("impulse count out of range");
    double sum = 0.0;
    for (int i = 0; i < s->n; ++i) {
      if (!std::isfinite(s->a[i]) || !std::isfinite(s->t_s[i]) || s->t_s[i] < 0.0 ||
          (i > 0 && s->t_s[i] < s->t_s[i - 1]))
        return shaper_error("impulse times must be finite, >= 0 and increasing");
      sum += s->a[i];
    }
    if (std::abs(sum - 1.0) > 1e-9) return shaper_error("impulse amplitudes must sum to 1");
    if (s->t_s[s->n - 1] / period_s > kMaxRingSamples)
      return shaper_error("shaper longer than " + std::to_string(kMaxRingSamples) + " periods");
    preview_ = std::max(preview_, static_cast<int>(std::ceil(centre_time_s(*s) / period_s - kTimeEps)));
  }
  // Taps: y(t_k) = sum_i A_i r(t_k + t_c - t_i); t_k + tau lies at age P - tau / T (fractional) from
  // the newest sample t_{k+P}; linear interpolation between the two neighbouring ages.
  int max_age = preview_;
  for (int j = 0; j < 3; ++j) {
    filters_[j].reset();
    const auto& s = setup.shapers[j];
    if (!s) continue;
    Filter f;
    const double t_c_s = centre_time_s(*s);
    for (int i = 0; i < s->n; ++i) {
      const double age = preview_ - (t_c_s - s->t_s[i]) / period_s;
      const int a0 = std::max(0, static_cast<int>(std::floor(age + kTimeEps)));
      double frac = age - a0;
      if (frac < kTimeEps) frac = 0.0;
      f.taps[f.n_taps++] = Tap{a0, s->a[i] * (1.0 - frac)};
      if (frac > 0.0) f.taps[f.n_taps++] = Tap{a0 + 1, s->a[i] * frac};
      max_age = std::max(max_age, frac > 0.0 ? a0 + 1 : a0);
    }
    filters_[j] = f;
  }
  ring_.assign(static_cast<std::size_t>(max_age) + 1, Sample{});
  head_ = 0;
  return Status::Ok();
}

const InputShaper::Sample& InputShaper::at_age_(int age) const {
  const int n = static_cast<int>(ring_.size());
  int i = head_ - age;
  if (i < 0) i += n;
  return ring_[static_cast<std::size_t>(i)];
}

double InputShaper::read_(int channel, const Filter& f) const {
  double y = 0.0;
  for (int i = 0; i < f.n_taps; ++i) y += f.taps[i].weight * at_age_(f.taps[i].age)[channel];
  return y;
}

void InputShaper::reset(const FeedforwardInput& at) {
  Sample s{};
  for (int j = 0; j < kJoints; ++j) s[j] = at.r_mm[j];
  for (int j = 0; j < 3; ++j) s[kJoints + j] = at.nozzle_mm[j];
  for (Sample& x : ring_) x = s;
  head_ = 0;
}

void InputShaper::step(const FeedforwardInput& in, JointArray& u_mm) {
  if (ring_.empty()) {  // not configured: F = 1
    u_mm = in.r_mm;
    return;
  }
  head_ = (head_ + 1 == static_cast<int>(ring_.size())) ? 0 : head_ + 1;
  Sample& s = ring_[static_cast<std::size_t>(head_)];
  for (int j = 0; j < kJoints; ++j) s[j] = in.r_mm[j];
  for (int j = 0; j < 3; ++j) s[kJoints + j] = in.nozzle_mm[j];

  const Sample& now = at_age_(preview_);  // the reference at t_k
  for (int j = 0; j < kJoints; ++j) u_mm[j] = now[j];
  if (cartesian_) {
    // q = M x: the joints get r(t_k) + M (x_shaped - x(t_k)).
    std::array<double, 3> dx_mm{};
    for (int j = 0; j < 3; ++j)
      if (filters_[j]) dx_mm[j] = read_(kJoints + j, *filters_[j]) - now[kJoints + j];
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) u_mm[i] += map_[i][j] * dx_mm[j];
  } else {
    for (int j = 0; j < 3; ++j)
      if (filters_[j]) u_mm[j] = read_(j, *filters_[j]);
  }
}

}  // namespace feedloop::control
