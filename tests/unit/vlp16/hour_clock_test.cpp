#include "cndt/vlp16/hour_clock.hpp"

#include <gtest/gtest.h>

namespace cndt::vlp16 {
namespace {

using std::chrono::nanoseconds;
constexpr std::int64_t kHourNs = 3'600'000'000'000;
// 2026-01-01T10:00:00Z
constexpr std::int64_t kTen = 1'767'261'600'000'000'000;

TEST(HourClock, TakesTheHourFromTheReference) {
  HourClock c;
  const auto t = c.resolve(1'000'000, nanoseconds(kTen + 1'002'000'000));
  EXPECT_EQ(t.count(), kTen + 1'000'000'000);
}

TEST(HourClock, ChoosesThePreviousHourWhenTheReferenceIsJustPastIt) {
  HourClock c;
  // Sensor says 59:59.9, reference already at 10:00:00.2 -> the packet is from 9:59:59.9.
  const auto t = c.resolve(3'599'900'000u, nanoseconds(kTen + 200'000'000));
  EXPECT_EQ(t.count(), kTen - 100'000'000);
}

TEST(HourClock, RollsOverWhenTheSensorClockWraps) {
  HourClock c;
  c.resolve(3'599'999'000u, nanoseconds(kTen - 1'000'000));
  const auto t = c.resolve(328u, nanoseconds(kTen - 1'000'000));  // reference not updated
  EXPECT_EQ(t.count(), kTen + 328'000);
  EXPECT_EQ(c.rollovers(), 1u);
  c.resolve(1'000'000'000u, nanoseconds(0));  // the reference is ignored from now on
  const auto later = c.resolve(2'000'000'000u, nanoseconds(0));
  EXPECT_EQ(later.count(), kTen + 2'000'000'000'000);
}

TEST(HourClock, LatePacketFromBeforeTheRolloverKeepsItsHour) {
  HourClock c;
  c.resolve(3'599'999'000u, nanoseconds(kTen));
  c.resolve(500u, nanoseconds(kTen));
  const auto late = c.resolve(3'599'999'900u, nanoseconds(kTen));
  EXPECT_EQ(late.count(), kTen - 100'000);
  const auto next = c.resolve(1'800u, nanoseconds(kTen));
  EXPECT_EQ(next.count(), kTen + 1'800'000);
  EXPECT_EQ(c.rollovers(), 1u);
}

TEST(HourClock, ManyHoursAccumulate) {
  HourClock c;
  std::int64_t expected = kTen;
  c.resolve(0, nanoseconds(kTen));
  for (int h = 1; h <= 30; ++h) {
    // The clock moves on in steps shorter than half an hour, as a packet stream does.
    c.resolve(1'200'000'000u, nanoseconds(0));
    c.resolve(2'400'000'000u, nanoseconds(0));
    expected = kTen + h * kHourNs;
    EXPECT_EQ(c.resolve(0, nanoseconds(0)).count(), expected);
  }
}

}  // namespace
}  // namespace cndt::vlp16
