// Plausibility of one joint's encoder on the host loop (control.loop: host), so that the loop
// stops with a clear error instead of chasing a bad sensor (issue 5, "safe behaviour when an
// encoder fails"), judged on the samples' timestamps, not on a count of servo periods (issue 13:
// one late wake-up made a normal move look like a jump). Three faults:
//   jump            a sample y at time t is implausible when
//                     |y - y_good| > max_speed_mm_s (t - t_good) + jump_margin_mm
//                   with (t_good, y_good) the last accepted sample: a distance the carriage cannot
//                   travel in the elapsed time. An implausible sample is rejected (not used by the
//                   PI; sample_accepted() says so) and the next one is judged against the same good
//                   sample over the longer time; reject_limit rejected samples in a row are the
//                   fault, as is a non-finite reading. The rule is the device loop's own
//                   (drivers/device/encoder_plausibility.hpp, run here on nm and ns), so host and
//                   MCU judge a sample alike;
//   stale           no new sample for more than stale_s (sample time, else arrival) while the
//                   reference moves;
//   following_error |r - y| > max_following_error_mm on an accepted sample (r = desired carriage
//                   position at the sample's time).
// The first fault latches (with its message in a fixed buffer, written without allocation) until
// reset(); the servo stops motion on it.
// Owner: servo thread. configure() validates; update() and reset() are RT-safe.
#pragma once

#include <array>
#include <cmath>  // NAN
#include <cstdint>
#include <string>

#include "core/result.hpp"
#include "drivers/device/encoder_plausibility.hpp"

namespace feedloop::control {

enum class EncoderFault { none, jump, stale, following_error };
const char* to_string(EncoderFault fault);

struct EncoderGuardParams {
  std::string axis = "x";         // named in the messages (at most 7 characters kept)
  double max_speed_mm_s = 600.0;  // no carriage moves faster (ringing included)
  double jump_margin_mm = 0.05;  // beyond max_speed x elapsed time: noise, quantisation, timestamps
  int reject_limit = 3;          // implausible samples in a row before the fault
  double max_following_error_mm = 2.0;
  double stale_s = 0.01;        // samples may be missing this long while moving
  double moving_eps_mm = 1e-6;  // the reference moved when it changes more per update
};

struct EncoderGuardInput {
  bool fresh = false;          // a new encoder sample arrived this period
  double encoder_mm = 0.0;     // that sample (ignored when !fresh)
  double sample_time_s = NAN;  // when it was sampled (monotonic s, the servo's clock); NaN: now_s
  double now_s = 0.0;          // this period's time (same clock)
  double reference_mm = 0.0;   // desired carriage position at the sample's time
};

class EncoderGuard {
 public:
  static constexpr int kMessageCapacity = 128;

  Status configure(const EncoderGuardParams& params);

  // RT-safe. One period; returns the latched fault (none while healthy).
  EncoderFault update(const EncoderGuardInput& in);

  // RT-safe. Clears the fault and forgets the previous samples (after the operator re-enables).
  void reset();
  // RT-safe. Motion restarts after a rest: forgets the previous samples and their times (the
  // loop was open meanwhile), keeps a latched fault.
  void restart();

  EncoderFault fault() const { return fault_; }
  // "x: encoder jump of 3.000 mm in 1.0 ms (limit 0.650 mm)"; empty while healthy.
  const char* message() const { return message_.data(); }
  // The last update's sample was fresh, finite and plausible: the loop may use it.
  bool sample_accepted() const { return accepted_; }
  std::int64_t rejected_samples() const { return rejected_total_; }
  // Time (s) between the last update's sample and the good sample before it (0 before the second).
  double last_interval_s() const { return last_interval_s_; }

 private:
  void trip_(EncoderFault fault);
  void append_(const char* text);
  void append_mm_(double value);
  void append_ms_(double seconds);
  void append_int_(std::int64_t value);

  EncoderGuardParams p_{};
  device::EncoderPlausibility plausibility_{};
  std::array<char, 8> axis_{};
  EncoderFault fault_ = EncoderFault::none;
  std::array<char, kMessageCapacity> message_{};
  int length_ = 0;
  bool accepted_ = false;
  std::int64_t rejected_total_ = 0;
  double last_interval_s_ = 0.0;
  bool have_report_ = false;
  double last_report_s_ = 0.0;  // sample time (else arrival) of the last report
  bool moved_since_report_ = false;
  bool have_reference_ = false;
  double last_reference_mm_ = 0.0;
};

}  // namespace feedloop::control
