// Input shapers ZV, MZV and EI as a feedforward path F (control/feedforward.hpp): the baselines
// the issue asks for, with the impulse sets Klipper defines (klippy/extras/shaper_defs.py) for a
// natural frequency f and damping ratio zeta. With omega_d = 2 pi f sqrt(1 - zeta^2),
// t_d = 1 / (f sqrt(1 - zeta^2)) (the damped period) and impulses (A_i, t_i), sum A_i = 1:
//   ZV : K = exp(-zeta pi / sqrt(1 - zeta^2)); A ~ [1, K], t = [0, t_d / 2]
//   MZV: K = exp(-0.75 zeta pi / sqrt(1 - zeta^2)); A ~ [1 - 1/sqrt2, (sqrt2 - 1) K, (1 - 1/sqrt2) K^2],
//        t = [0, 0.375 t_d, 0.75 t_d]
//   EI : Klipper's polynomial fit in zeta for a tolerated vibration V_tol = 5 %, t = [0, t2 t_d, t_d]
// (A ~ means "normalised to sum 1"). The shaped command is centred on the shaper's centre of time
// t_c = sum A_i t_i so that it has no net lag:
//   y(t_k) = sum_i A_i r(t_k - t_i + t_c)
// which needs r up to t_k + t_c: preview_samples() P = ceil(t_c / T). r between the period samples
// is interpolated linearly. The residual vibration of a second-order mode (f_m, zeta_m) after a
// shaped step (Singer & Seering) is
//   V = exp(-zeta_m w t_N) sqrt((sum A_i e^{zeta_m w t_i} cos(w_d t_i))^2
//                               + (sum A_i e^{zeta_m w t_i} sin(w_d t_i))^2),  w = 2 pi f_m,
// w_d = w sqrt(1 - zeta_m^2): ZV and MZV give V = 0 at their design point, EI V = V_tol.
//
// Where the joints are a linear map of the nozzle position (cartesian, corexy: q = M x) the nozzle's
// X and Y are shaped, each with its own shaper, and the joints get r + M (x_shaped - x): exactly
// the Cartesian shaping even on corexy. Otherwise (delta) each carriage is shaped in joint space.
// Z (or an unshaped axis) and the extruder pass through, delayed by P periods like the rest.
// Owner: servo thread. configure() allocates the ring of past references; step() and reset() are
// RT-safe.
#pragma once

#include <array>
#include <optional>
#include <vector>

#include "control/feedforward.hpp"
#include "core/result.hpp"

namespace feedloop::control {

inline constexpr int kMaxImpulses = 5;

// The shaper families (Klipper's names).
enum class ShaperType { zv, mzv, ei };

// An impulse sequence: amplitudes A_i (sum 1) at times t_i (s), t_0 = 0, increasing.
struct Impulses {
  int n = 0;
  std::array<double, kMaxImpulses> a{};
  std::array<double, kMaxImpulses> t_s{};
};

// Klipper's ZV / MZV / EI for natural frequency f and damping ratio zeta, normalised to sum 1.
// Errors: f not > 0, zeta outside [0, 1) (EI: outside [0, 0.4], where Klipper's fit is valid).
Result<Impulses> make_impulses(ShaperType type, double freq_hz, double damping);
const char* shaper_name(ShaperType type);
// t_c = sum A_i t_i / sum A_i.
double centre_time_s(const Impulses& s);
// V(f, zeta) above: residual vibration of a mode at freq_hz with damping ratio `damping` after a
// shaped step, relative to the unshaped step (1 = no reduction).
double residual_vibration(const Impulses& s, double freq_hz, double damping);

struct InputShaperSetup {
  double period_s = 1e-3;
  // linear_map set (cartesian, corexy): shapers[0..2] shape the nozzle's x, y, z. Not set (delta):
  // shapers[i] shapes joint i. nullopt: that axis / joint passes through.
  std::array<std::optional<Impulses>, 3> shapers{};
  std::optional<std::array<std::array<double, 3>, 3>> linear_map;  // q = M x, rows = joints
};

// The setup from the printer config: engine::input_shaper_setup (engine/control_config.hpp).

class InputShaper final : public Feedforward {
 public:
  // Validates and sizes the ring (may allocate).
  Status configure(const InputShaperSetup& setup);

  const char* name() const override { return "input_shaper"; }
  int preview_samples() const override { return preview_; }
  void reset(const FeedforwardInput& at) override;                // RT-safe
  void step(const FeedforwardInput& in, JointArray& u_mm) override;  // RT-safe

  // Samples in the ring (P + the shaper's past span + 2).
  int ring_size() const { return static_cast<int>(ring_.size()); }

 private:
  // One weighted read of the ring: value at `age` periods before the newest sample.
  struct Tap {
    int age = 0;
    double weight = 0.0;
  };
  struct Filter {
    int n_taps = 0;
    std::array<Tap, 2 * kMaxImpulses> taps{};
  };
  static constexpr int kChannels = kJoints + 3;  // r_mm (joints) then nozzle_mm (x, y, z)
  using Sample = std::array<double, kChannels>;

  double read_(int channel, const Filter& f) const;
  const Sample& at_age_(int age) const;

  bool cartesian_ = false;
  std::array<std::array<double, 3>, 3> map_{};
  std::array<std::optional<Filter>, 3> filters_{};  // per Cartesian axis or per joint
  int preview_ = 0;
  std::vector<Sample> ring_;  // sized in configure()
  int head_ = 0;              // index of the newest sample (t_{k+P})
};

}  // namespace feedloop::control
