// Encoder plausibility checks and their allocation-free messages (see encoder_guard.hpp).
#include "control/encoder_guard.hpp"

#include <cmath>  // std::abs, std::isfinite, std::llround

namespace feedloop::control {

const char* to_string(EncoderFault fault) {
  switch (fault) {
    case EncoderFault::none: return "none";
    case EncoderFault::jump: return "jump";
    case EncoderFault::stale: return "stale";
    case EncoderFault::following_error: return "following_error";
  }
  return "?";
}

Status EncoderGuard::configure(const EncoderGuardParams& params) {
  auto bad = [](const char* what) { return Status(Error{std::string("encoder guard: ") + what, {}}); };
  if (!std::isfinite(params.max_jump_mm) || params.max_jump_mm <= 0.0) return bad("max_jump_mm must be > 0");
  if (!std::isfinite(params.max_following_error_mm) || params.max_following_error_mm <= 0.0)
    return bad("max_following_error_mm must be > 0");
  if (params.stale_periods < 1) return bad("stale_periods must be >= 1");
  if (!std::isfinite(params.moving_eps_mm) || params.moving_eps_mm < 0.0)
    return bad("moving_eps_mm must be >= 0");
  p_ = params;
  axis_.fill('\0');
  for (std::size_t i = 0; i + 1 < axis_.size() && i < p_.axis.size(); ++i) axis_[i] = p_.axis[i];
  reset();
  return Status::Ok();
}

void EncoderGuard::reset() {
  fault_ = EncoderFault::none;
  message_.fill('\0');
  length_ = 0;
  have_report_ = false;
  since_report_ = 0;
  moved_since_report_ = false;
  have_reference_ = false;
}

EncoderFault EncoderGuard::update(const EncoderGuardInput& in) {
  if (fault_ != EncoderFault::none) return fault_;
  if (have_reference_ && std::abs(in.reference_mm - last_reference_mm_) > p_.moving_eps_mm)
    moved_since_report_ = true;
  have_reference_ = true;
  last_reference_mm_ = in.reference_mm;
  ++since_report_;

  if (!in.fresh) {
    if (have_report_ && moved_since_report_ && since_report_ > p_.stale_periods) {
      trip_(EncoderFault::stale);
      append_("no encoder report for ");
      append_int_(since_report_);
      append_(" periods while moving (limit ");
      append_int_(p_.stale_periods);
      append_(")");
    }
    return fault_;
  }

  if (!std::isfinite(in.encoder_mm)) {
    trip_(EncoderFault::jump);
    append_("encoder reading is not a finite number");
    return fault_;
  }
  if (have_report_) {
    // The carriage may move max_jump_mm per period: a report after n periods may differ by n times that.
    const double jump_mm = in.encoder_mm - last_mm_;
    const double limit_mm = p_.max_jump_mm * since_report_;
    if (std::abs(jump_mm) > limit_mm) {
      trip_(EncoderFault::jump);
      append_("encoder jump of ");
      append_mm_(jump_mm);
      append_(" mm in ");
      append_int_(since_report_);
      append_(" period(s) (limit ");
      append_mm_(limit_mm);
      append_(" mm)");
      return fault_;
    }
  }
  have_report_ = true;
  last_mm_ = in.encoder_mm;
  since_report_ = 0;
  moved_since_report_ = false;

  const double error_mm = in.reference_mm - in.encoder_mm;
  if (std::abs(error_mm) > p_.max_following_error_mm) {
    trip_(EncoderFault::following_error);
    append_("following error ");
    append_mm_(error_mm);
    append_(" mm (limit ");
    append_mm_(p_.max_following_error_mm);
    append_(" mm)");
  }
  return fault_;
}

void EncoderGuard::trip_(EncoderFault fault) {
  fault_ = fault;
  message_.fill('\0');
  length_ = 0;
  append_(axis_.data());
  append_(": ");
}

void EncoderGuard::append_(const char* text) {
  while (*text != '\0' && length_ + 1 < kMessageCapacity) message_[length_++] = *text++;
  message_[length_] = '\0';
}

void EncoderGuard::append_int_(std::int64_t value) {
  char digits[24];
  int n = 0;
  const bool negative = value < 0;
  std::uint64_t v = negative ? 0ULL - static_cast<std::uint64_t>(value) : static_cast<std::uint64_t>(value);
  do {
    digits[n++] = static_cast<char>('0' + v % 10);
    v /= 10;
  } while (v != 0);
  if (negative) append_("-");
  char one[2] = {0, 0};
  while (n > 0) {
    one[0] = digits[--n];
    append_(one);
  }
}

// Fixed point with 3 decimals (no printf: it may allocate for some values).
void EncoderGuard::append_mm_(double value) {
  if (!std::isfinite(value)) {
    append_("nan");
    return;
  }
  constexpr double kMax = 1e12;
  if (value > kMax) value = kMax;
  if (value < -kMax) value = -kMax;
  const std::int64_t milli = std::llround(value * 1000.0);
  if (milli < 0) append_("-");
  const std::uint64_t m = milli < 0 ? 0ULL - static_cast<std::uint64_t>(milli) : static_cast<std::uint64_t>(milli);
  append_int_(static_cast<std::int64_t>(m / 1000));
  append_(".");
  const std::uint64_t frac = m % 1000;
  char three[4] = {static_cast<char>('0' + frac / 100), static_cast<char>('0' + (frac / 10) % 10),
                   static_cast<char>('0' + frac % 10), 0};
  append_(three);
}

}  // namespace feedloop::control
