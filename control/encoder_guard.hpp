// Plausibility of one joint's encoder, so that the loop stops with a clear error instead of
// chasing a bad sensor (issue 5, "safe behaviour when an encoder fails"). Three faults:
//   jump            |x_enc[n] - x_enc[n-1]| > max_jump_mm x (periods since the previous report),
//                   or a non-finite reading;
//   stale           no new report for more than stale_periods periods while the reference moves;
//   following_error |r - x_enc| > max_following_error_mm on a report (r = desired carriage position).
// The first fault latches (with its message in a fixed buffer, written without allocation) until
// reset(); the servo stops motion on it.
// Owner: servo thread. configure() validates; update() and reset() are RT-safe.
#pragma once

#include <array>
#include <cstdint>
#include <string>

#include "core/result.hpp"

namespace feedloop::control {

enum class EncoderFault { none, jump, stale, following_error };
const char* to_string(EncoderFault fault);

struct EncoderGuardParams {
  std::string axis = "x";               // named in the messages (at most 7 characters kept)
  double max_jump_mm = 1.0;             // per period between consecutive reports
  double max_following_error_mm = 2.0;
  int stale_periods = 10;               // reports may be missing this long while moving
  double moving_eps_mm = 1e-6;          // the reference moved when it changes more per period
};

struct EncoderGuardInput {
  bool fresh = false;         // a new encoder report arrived this period
  double encoder_mm = 0.0;    // that report (ignored when !fresh)
  double reference_mm = 0.0;  // desired carriage position this period
};

class EncoderGuard {
 public:
  static constexpr int kMessageCapacity = 128;

  Status configure(const EncoderGuardParams& params);

  // RT-safe. One period; returns the latched fault (none while healthy).
  EncoderFault update(const EncoderGuardInput& in);

  // RT-safe. Clears the fault and forgets the previous report (after the operator re-enables).
  void reset();

  EncoderFault fault() const { return fault_; }
  // "x: encoder jump of 3.000 mm in 1 period(s) (limit 1.000 mm)"; empty while healthy.
  const char* message() const { return message_.data(); }
  int periods_since_report() const { return since_report_; }

 private:
  void trip_(EncoderFault fault);
  void append_(const char* text);
  void append_mm_(double value);
  void append_int_(std::int64_t value);

  EncoderGuardParams p_{};
  std::array<char, 8> axis_{};
  EncoderFault fault_ = EncoderFault::none;
  std::array<char, kMessageCapacity> message_{};
  int length_ = 0;
  bool have_report_ = false;
  double last_mm_ = 0.0;
  int since_report_ = 0;         // periods since the last report
  bool moved_since_report_ = false;
  bool have_reference_ = false;
  double last_reference_mm_ = 0.0;
};

}  // namespace feedloop::control
