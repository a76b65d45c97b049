// Float -> int64 conversions and int64 sums for the device's arithmetic, saturating instead of
// undefined: NaN -> 0, beyond int64 -> its bounds. Parameters and targets come from the wire, so
// any float may reach them (found by fuzz/fuzz_mcu_device.cpp). Header-only, no heap, no
// exceptions.
#pragma once

#include <cstdint>

namespace feedloop::device {

inline int64_t saturate_i64(float x) {
  if (!(x == x)) return 0;
  if (x >= 9.2233720368547758e18f) return INT64_MAX;  // 2^63
  if (x <= -9.2233720368547758e18f) return INT64_MIN;
  return static_cast<int64_t>(x);
}

inline int64_t round_saturate_i64(float x) { return saturate_i64(x >= 0.0f ? x + 0.5f : x - 0.5f); }

inline int32_t round_saturate_i32(float x) {
  const int64_t r = round_saturate_i64(x);
  return r > INT32_MAX ? INT32_MAX : r < INT32_MIN ? INT32_MIN : static_cast<int32_t>(r);
}

inline int64_t add_saturate_i64(int64_t a, int64_t b) {
  int64_t r = 0;
  if (__builtin_add_overflow(a, b, &r)) return b > 0 ? INT64_MAX : INT64_MIN;
  return r;
}

inline int64_t sub_saturate_i64(int64_t a, int64_t b) {
  int64_t r = 0;
  if (__builtin_sub_overflow(a, b, &r)) return b < 0 ? INT64_MAX : INT64_MIN;
  return r;
}

inline int64_t mul_saturate_i64(int64_t a, int64_t b) {
  int64_t r = 0;
  if (__builtin_mul_overflow(a, b, &r)) return (a < 0) != (b < 0) ? INT64_MIN : INT64_MAX;
  return r;
}

}  // namespace feedloop::device
