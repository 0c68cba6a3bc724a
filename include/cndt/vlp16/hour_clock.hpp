// Turns the sensor's "microseconds past the hour" into absolute time.
#pragma once

#include <chrono>
#include <cstdint>

namespace cndt::vlp16 {

/// The first packet takes its hour from a reference clock (capture record time or host receive
/// time), choosing the hour that puts the packet within half an hour of the reference. After that
/// the hour advances only by the sensor clock itself: a drop of more than half an hour is a
/// rollover; a late packet from just before a rollover keeps the previous hour. All arithmetic is
/// signed 64-bit.
class HourClock {
 public:
  std::chrono::nanoseconds resolve(std::uint32_t toh_us,
                                   std::chrono::nanoseconds reference) noexcept;
  void reset() noexcept { initialised_ = false; }
  [[nodiscard]] std::uint64_t rollovers() const noexcept { return rollovers_; }

 private:
  bool initialised_ = false;
  std::int64_t hour_start_us_ = 0;
  std::int64_t last_toh_us_ = 0;
  std::uint64_t rollovers_ = 0;
};

}  // namespace cndt::vlp16
