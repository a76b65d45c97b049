// Encoder plausibility checks and their allocation-free messages (see encoder_guard.hpp).
#include "control/encoder_guard.hpp"

#include <cmath>  // std::abs, std::copysign, std::isfinite, std::llround

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

namespace {
constexpr double kNmPerMm = 1e6;
constexpr double kNsPerS = 1e9;
constexpr double kMaxAbsMm = 1e9;  // 1000 km: beyond any axis; keeps the nm count inside int64

std::int64_t to_nm(double mm) {
  const double c = mm > kMaxAbsMm ? kMaxAbsMm : mm < -kMaxAbsMm ? -kMaxAbsMm : mm;
  return std::llround(c * kNmPerMm);
}
// Monotonic seconds -> ns (a clock of 1 GHz for the shared plausibility rule).
std::int64_t to_ns(double s) {
  constexpr double kMaxS = 9.0e9;  // 285 years of uptime
  const double c = s > kMaxS ? kMaxS : s < -kMaxS ? -kMaxS : s;
  return std::llround(c * kNsPerS);
}
}  // namespace

Status EncoderGuard::configure(const EncoderGuardParams& params) {
  auto bad = [](const char* what) { return Status(Error{std::string("encoder guard: ") + what, {}}); };
  if (!std::isfinite(params.max_speed_mm_s) || params.max_speed_mm_s <= 0.0)
    return bad("max_speed_mm_s must be > 0");
  if (!std::isfinite(params.jump_margin_mm) || params.jump_margin_mm <= 0.0)
    return bad("jump_margin_mm must be > 0");
  if (params.reject_limit < 1) return bad("reject_limit must be >= 1");
  if (!std::isfinite(params.max_following_error_mm) || params.max_following_error_mm <= 0.0)
    return bad("max_following_error_mm must be > 0");
  if (!std::isfinite(params.stale_s) || params.stale_s <= 0.0) return bad("stale_s must be > 0");
  if (!std::isfinite(params.moving_eps_mm) || params.moving_eps_mm < 0.0)
    return bad("moving_eps_mm must be >= 0");
  p_ = params;
  plausibility_.configure(static_cast<float>(p_.max_speed_mm_s * kNmPerMm),
                          static_cast<float>(p_.jump_margin_mm * kNmPerMm),
                          static_cast<std::uint32_t>(p_.reject_limit), static_cast<float>(kNsPerS));
  axis_.fill('\0');
  for (std::size_t i = 0; i + 1 < axis_.size() && i < p_.axis.size(); ++i) axis_[i] = p_.axis[i];
  reset();
  return Status::Ok();
}

void EncoderGuard::reset() {
  fault_ = EncoderFault::none;
  message_.fill('\0');
  length_ = 0;
  restart();
}

void EncoderGuard::restart() {
  plausibility_.reset();
  accepted_ = false;
  last_interval_s_ = 0.0;
  have_report_ = false;
  moved_since_report_ = false;
  have_reference_ = false;
}

EncoderFault EncoderGuard::update(const EncoderGuardInput& in) {
  accepted_ = false;
  if (fault_ != EncoderFault::none) return fault_;
  if (have_reference_ && std::abs(in.reference_mm - last_reference_mm_) > p_.moving_eps_mm)
    moved_since_report_ = true;
  have_reference_ = true;
  last_reference_mm_ = in.reference_mm;
  const double sample_s = std::isfinite(in.sample_time_s) ? in.sample_time_s : in.now_s;

  if (!in.fresh) {
    const double silent_s = in.now_s - last_report_s_;
    if (have_report_ && moved_since_report_ && silent_s > p_.stale_s) {
      trip_(EncoderFault::stale);
      append_("no encoder sample for ");
      append_ms_(silent_s);
      append_(" ms while moving (limit ");
      append_ms_(p_.stale_s);
      append_(" ms)");
    }
    return fault_;
  }
  have_report_ = true;
  last_report_s_ = sample_s;
  moved_since_report_ = false;

  if (!std::isfinite(in.encoder_mm)) {
    trip_(EncoderFault::jump);
    append_("encoder reading is not a finite number");
    return fault_;
  }
  // The device loop's rule on timestamps (drivers/device/encoder_plausibility.hpp).
  const bool had_good = plausibility_.have_good();
  const std::int64_t good_ns = plausibility_.good_clock();
  const std::int64_t now_ns = to_ns(sample_s);
  const device::EncoderVerdict verdict = plausibility_.check(now_ns, to_nm(in.encoder_mm));
  last_interval_s_ = had_good ? static_cast<double>(now_ns - good_ns) / kNsPerS : 0.0;
  if (verdict != device::EncoderVerdict::kGood) {
    ++rejected_total_;
    if (verdict == device::EncoderVerdict::kFault) {
      trip_(EncoderFault::jump);
      append_("encoder jump of ");
      append_mm_(std::copysign(static_cast<double>(plausibility_.last_jump_nm()) / kNmPerMm,
                               in.encoder_mm - static_cast<double>(plausibility_.good_nm()) / kNmPerMm));
      append_(" mm in ");
      append_ms_(last_interval_s_);
      append_(" ms (limit ");
      append_mm_(static_cast<double>(plausibility_.last_allowed_nm()) / kNmPerMm);
      append_(" mm; ");
      append_int_(static_cast<std::int64_t>(plausibility_.rejected_in_row()));
      append_(" samples in a row)");
    }
    return fault_;
  }
  accepted_ = true;

  const double error_mm = in.reference_mm - in.encoder_mm;
  if (std::abs(error_mm) > p_.max_following_error_mm) {
    accepted_ = false;
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

// Milliseconds with one decimal.
void EncoderGuard::append_ms_(double seconds) {
  if (!std::isfinite(seconds)) {
    append_("nan");
    return;
  }
  constexpr double kMaxS = 1e9;
  const double s = seconds > kMaxS ? kMaxS : seconds < -kMaxS ? -kMaxS : seconds;
  const std::int64_t tenths = std::llround(s * 1e4);
  if (tenths < 0) append_("-");
  const std::uint64_t t = tenths < 0 ? 0ULL - static_cast<std::uint64_t>(tenths) : static_cast<std::uint64_t>(tenths);
  append_int_(static_cast<std::int64_t>(t / 10));
  char one[3] = {'.', static_cast<char>('0' + t % 10), 0};
  append_(one);
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
