#include "cndt/output/can_codec.hpp"

#include <algorithm>
#include <cmath>

#include "cndt/core/bytes.hpp"
#include "cndt/output/crc.hpp"

namespace cndt::output {
namespace {

// Signals as raw bit fields of the frame read as one little-endian 64-bit word (Intel order:
// bit i of the word is bit i % 8 of byte i / 8, which is the DBC's start-bit numbering).
void put(std::uint64_t& word, unsigned start, unsigned len, std::uint64_t raw) noexcept {
  const std::uint64_t mask = len == 64 ? ~0ull : ((1ull << len) - 1);
  word = (word & ~(mask << start)) | ((raw & mask) << start);
}
std::uint64_t get(std::uint64_t word, unsigned start, unsigned len) noexcept {
  const std::uint64_t mask = len == 64 ? ~0ull : ((1ull << len) - 1);
  return (word >> start) & mask;
}
std::int64_t get_signed(std::uint64_t word, unsigned start, unsigned len) noexcept {
  const std::uint64_t raw = get(word, start, len);
  const std::uint64_t sign = 1ull << (len - 1);
  return static_cast<std::int64_t>(raw ^ sign) - static_cast<std::int64_t>(sign);
}

// value / step rounded and clamped to a signed field of `len` bits; sets `clamped` when outside.
std::uint64_t to_signed_raw(double value, double step, unsigned len, bool& clamped) noexcept {
  const double hi = std::ldexp(1.0, static_cast<int>(len) - 1) - 1.0;
  double r = std::isfinite(value) ? std::round(value / step) : 0.0;
  if (!std::isfinite(value) || r > hi || r < -hi) {
    clamped = true;
    r = std::clamp(r, -hi, hi);
  }
  return static_cast<std::uint64_t>(static_cast<std::int64_t>(r));
}
std::uint64_t to_unsigned_raw(double value, double step, unsigned len, bool& clamped) noexcept {
  const double hi = std::ldexp(1.0, static_cast<int>(len)) - 1.0;
  double r = std::isfinite(value) ? std::round(value / step) : 0.0;
  if (!std::isfinite(value) || r > hi || r < 0.0) {
    clamped = true;
    r = std::clamp(r, 0.0, hi);
  }
  return static_cast<std::uint64_t>(r);
}

CanFrame finish_frame(std::uint32_t id, bool extended, std::uint64_t word) noexcept {
  CanFrame f;
  f.id = id;
  f.extended = extended;
  f.len = 8;
  core::store_le64(f.data, 0, word);
  f.data[0] = crc8_sae_j1850(core::ByteSpan(f.data).subspan(1));
  return f;
}

}  // namespace

CanPoseFrames encode_pose_frames(const PoseMessage& pose, std::uint8_t counter,
                                 std::uint32_t base_id, bool extended) noexcept {
  bool clamped = false;
  const unsigned c = counter & 0x0Fu;
  std::uint64_t time = 0, xy = 0, z = 0, orient = 0, status = 0;
  for (std::uint64_t* w : {&time, &xy, &z, &orient, &status}) put(*w, 8, 4, c);

  const std::int64_t ns = std::max<std::int64_t>(pose.stamp_ns, 0);
  const std::int64_t seconds = std::min<std::int64_t>(ns / 1'000'000'000, 0xFFFFFFFFll);
  put(time, 12, 20, static_cast<std::uint64_t>((ns % 1'000'000'000) / 1000));
  put(time, 32, 32, static_cast<std::uint64_t>(seconds));

  put(xy, 12, 26, to_signed_raw(pose.position.x(), kCanPositionStep, 26, clamped));
  put(xy, 38, 26, to_signed_raw(pose.position.y(), kCanPositionStep, 26, clamped));
  put(z, 12, 26, to_signed_raw(pose.position.z(), kCanPositionStep, 26, clamped));

  const Eigen::Vector3d rpy = roll_pitch_yaw(pose.orientation.normalized().toRotationMatrix());
  put(orient, 16, 16, to_signed_raw(rpy[0], kCanAngleStep, 16, clamped));
  put(orient, 32, 16, to_signed_raw(rpy[1], kCanAngleStep, 16, clamped));
  put(orient, 48, 16, to_signed_raw(rpy[2], kCanAngleStep, 16, clamped));

  bool cm_clamped = false;  // Cm outside 0..1 is the metric's business, not a range fault
  put(status, 16, 16, to_unsigned_raw(pose.cm, kCanCmStep, 16, cm_clamped));
  put(status, 32, 16, pose.scan_sequence & 0xFFFFu);
  put(status, 48, 16, std::min<std::uint32_t>(pose.points, 0xFFFFu));
  put(status, 12, 2, static_cast<std::uint64_t>(pose.status));
  put(status, 14, 1, (pose.flags & kPoseMapCorrected) != 0 ? 1u : 0u);
  put(status, 15, 1, clamped || (pose.flags & kPoseOutOfRange) != 0 ? 1u : 0u);

  return {finish_frame(base_id + kCanStatus, extended, status),
          finish_frame(base_id + kCanTime, extended, time),
          finish_frame(base_id + kCanPositionXY, extended, xy),
          finish_frame(base_id + kCanPositionZ, extended, z),
          finish_frame(base_id + kCanOrientation, extended, orient)};
}

bool can_crc_ok(const CanFrame& frame) noexcept {
  return frame.len == 8 && crc8_sae_j1850(core::ByteSpan(frame.data).subspan(1)) == frame.data[0];
}

std::optional<PoseMessage> CanPoseDecoder::feed(const CanFrame& frame) {
  if (frame.id < base_id_ || frame.id >= base_id_ + kCanFramesPerPose) return std::nullopt;
  const std::uint32_t idx = frame.id - base_id_;
  ++stats_.frames;
  if (frame.len != 8) {
    ++stats_.bad_length;
    return std::nullopt;
  }
  if (!can_crc_ok(frame)) {
    ++stats_.bad_crc;
    return std::nullopt;
  }
  const int counter = frame.data[1] & 0x0F;
  int& last = last_counter_[idx];
  if (last >= 0) {
    const int step = (counter - last) & 0x0F;
    if (step == 0) {
      ++stats_.counter_repeats;
      return std::nullopt;  // a stale repetition carries nothing new
    }
    if (step > 1) ++stats_.counter_gaps;
  }
  last = counter;
  if (group_counter_ != counter) {
    if (group_mask_ != 0) ++stats_.incomplete_poses;
    group_counter_ = counter;
    group_mask_ = 0;
  }
  group_[idx] = frame;
  group_mask_ |= 1u << idx;
  if (group_mask_ != (1u << kCanFramesPerPose) - 1) return std::nullopt;
  group_mask_ = 0;
  group_counter_ = -1;

  const auto word = [&](CanFrameIndex i) { return core::load_le64(group_[i].data, 0); };
  PoseMessage m;
  const std::uint64_t st = word(kCanStatus), tm = word(kCanTime), xy = word(kCanPositionXY),
                      z = word(kCanPositionZ), o = word(kCanOrientation);
  m.status = static_cast<PoseStatus>(get(st, 12, 2));
  if (get(st, 14, 1) != 0) m.flags |= kPoseMapCorrected;
  if (get(st, 15, 1) != 0) m.flags |= kPoseOutOfRange;
  m.cm = static_cast<double>(get(st, 16, 16)) * kCanCmStep;
  m.scan_sequence = static_cast<std::uint32_t>(get(st, 32, 16));
  m.points = static_cast<std::uint32_t>(get(st, 48, 16));
  m.stamp_ns = static_cast<std::int64_t>(get(tm, 32, 32)) * 1'000'000'000 +
               static_cast<std::int64_t>(get(tm, 12, 20)) * 1000;
  m.position = {static_cast<double>(get_signed(xy, 12, 26)) * kCanPositionStep,
                static_cast<double>(get_signed(xy, 38, 26)) * kCanPositionStep,
                static_cast<double>(get_signed(z, 12, 26)) * kCanPositionStep};
  m.orientation = Eigen::Quaterniond(
      from_roll_pitch_yaw(static_cast<double>(get_signed(o, 16, 16)) * kCanAngleStep,
                          static_cast<double>(get_signed(o, 32, 16)) * kCanAngleStep,
                          static_cast<double>(get_signed(o, 48, 16)) * kCanAngleStep));
  ++stats_.poses;
  return m;
}

void CanPoseDecoder::finish() {
  if (group_mask_ != 0) ++stats_.incomplete_poses;
  group_mask_ = 0;
  group_counter_ = -1;
}

}  // namespace cndt::output
