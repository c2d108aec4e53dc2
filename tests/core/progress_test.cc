// Durations in progress lines: seconds, then minutes, then hours, rounded to the second.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "sonicboom/core/progress.h"

namespace sonicboom {
namespace {

TEST(FormatDurationTest, SecondsMinutesAndHours) {
  EXPECT_EQ(FormatDuration(0.0), "0s");
  EXPECT_EQ(FormatDuration(59.4), "59s");
  EXPECT_EQ(FormatDuration(59.6), "1m00s");  // rounded before the unit is chosen
  EXPECT_EQ(FormatDuration(187.0), "3m07s");
  EXPECT_EQ(FormatDuration(3599.0), "59m59s");
  EXPECT_EQ(FormatDuration(3600.0), "1h00m");
  EXPECT_EQ(FormatDuration(47076.0), "13h04m");
  EXPECT_EQ(FormatDuration(-1.0), "?");
  EXPECT_EQ(FormatDuration(std::numeric_limits<double>::infinity()), "?");
  EXPECT_EQ(FormatDuration(std::nan("")), "?");
}

}  // namespace
}  // namespace sonicboom
