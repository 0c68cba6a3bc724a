#include "cndt/vlp16/hour_clock.hpp"

namespace cndt::vlp16 {
namespace {
constexpr std::int64_t kHourUs = 3'600'000'000;
constexpr std::int64_t kHalfHourUs = kHourUs / 2;

std::int64_t floor_div(std::int64_t a, std::int64_t b) {
  const std::int64_t q = a / b;
  return (a % b != 0 && (a < 0) != (b < 0)) ? q - 1 : q;
}
}  // namespace

std::chrono::nanoseconds HourClock::resolve(std::uint32_t toh_us,
                                            std::chrono::nanoseconds reference) noexcept {
  const auto toh = static_cast<std::int64_t>(toh_us);
  if (!initialised_) {
    const std::int64_t ref_us = floor_div(reference.count(), 1000);
    std::int64_t start = floor_div(ref_us, kHourUs) * kHourUs;
    const std::int64_t candidate = start + toh;
    if (candidate - ref_us > kHalfHourUs) start -= kHourUs;
    if (ref_us - candidate > kHalfHourUs) start += kHourUs;
    hour_start_us_ = start;
    last_toh_us_ = toh;
    initialised_ = true;
    return std::chrono::microseconds(hour_start_us_ + toh);
  }
  const std::int64_t step = toh - last_toh_us_;
  if (step < -kHalfHourUs) {
    hour_start_us_ += kHourUs;
    ++rollovers_;
  } else if (step > kHalfHourUs) {
    // A packet from before the last rollover, arriving late: it belongs to the previous hour.
    return std::chrono::microseconds(hour_start_us_ - kHourUs + toh);
  }
  last_toh_us_ = toh;
  return std::chrono::microseconds(hour_start_us_ + toh);
}

}  // namespace cndt::vlp16
