#include "core/result.hpp"

#include <gtest/gtest.h>

namespace feedloop {

TEST(Result, CarriesValueOrLocatedError) {
  Result<int> good = 42;
  ASSERT_TRUE(good.ok());
  EXPECT_EQ(*good, 42);
  Result<int> bad = Error{"bad value", {"printer.yaml", 12, 7}};
  ASSERT_FALSE(bad.ok());
  EXPECT_EQ(bad.error().to_string(), "printer.yaml:12:7: bad value");
  Status s = Error{"no location"};
  EXPECT_FALSE(s.ok());
  EXPECT_EQ(s.error().to_string(), "no location");
}

}  // namespace feedloop
