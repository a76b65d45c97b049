// ManeuverController::evaluate and ManeuverServo::update allocate nothing (they run in the servo
// thread): global operator new is counted around 20000 servo periods. Its own binary, since it
// replaces operator new.
#include <gtest/gtest.h>

#include <atomic>
#include <cstdlib>
#include <new>

#include "maneuver/servo.hpp"

namespace {
std::atomic<long> g_news{0};
}

void* operator new(std::size_t n) {
  g_news.fetch_add(1, std::memory_order_relaxed);
  if (void* p = std::malloc(n ? n : 1)) return p;
  throw std::bad_alloc();
}
// GCC (with -O2 and the sanitizers) pairs gtest's `new` with the built-in operator and warns that
// free() does not match; new and delete here are the replaced pair.
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"
#endif
void operator delete(void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic pop
#endif

namespace feedloop::maneuver {
namespace {

TEST(ManeuverAlloc, ServoUpdateAllocatesNothing) {
  std::vector<Vec3> wp;
  for (int i = 0; i <= 200; ++i) wp.emplace_back(1e-3 * i, (i % 2) * 0.3e-3, 0.0);  // zigzag: corners
  auto path = PiecewiseLinearPath::create(wp, Parameterization::arc_length);
  auto speed = SpeedAssignment::create(*path, SpeedProfile::sharp_corner_arc, SpeedParams{});
  ASSERT_TRUE(path.ok() && speed.ok());
  const CartesianDcPlant plant;
  ManeuverGains g;
  g.mu = 1e-3;
  const ManeuverController ctl(plant, g);
  ManeuverServo servo(*path, *speed, ctl, true);
  PlantState x;
  x.x1_m = path->point(0);
  const long before = g_news.load();
  int periods = 0;
  for (; periods < 20000 && !servo.finished(); ++periods) {
    const Vec3 w = servo.update(x, 2e-4);
    for (int i = 0; i < 2; ++i) plant.step_rk4(x, w, 1e-4);
  }
  const long news = g_news.load() - before;
  EXPECT_EQ(news, 0);
  EXPECT_GT(periods, 1000);
  EXPECT_GT(servo.segment(), 100u);  // it did travel through the corners
}

}  // namespace
}  // namespace feedloop::maneuver
