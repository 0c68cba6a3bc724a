#include "cndt/output/udp_codec.hpp"

#include "cndt/output/crc.hpp"

namespace cndt::output {
namespace {

constexpr std::array<std::uint8_t, 4> kMagic{'C', 'N', 'D', 'P'};
constexpr std::size_t kOffVersion = 4, kOffSize = 6, kOffSequence = 8, kOffScan = 12,
                      kOffStamp = 16, kOffPosition = 24, kOffQuaternion = 48, kOffCm = 80,
                      kOffStatus = 84, kOffReserved = 85, kOffFlags = 86, kOffPoints = 88,
                      kOffCrc = 92;

}  // namespace

PoseDatagram encode_pose_datagram(const PoseMessage& pose, std::uint32_t sequence) noexcept {
  PoseDatagram d{};
  core::MutableByteSpan b(d);
  for (std::size_t i = 0; i < kMagic.size(); ++i) b[i] = kMagic[i];
  core::store_le16(b, kOffVersion, kPoseDatagramVersion);
  core::store_le16(b, kOffSize, static_cast<std::uint16_t>(kPoseDatagramBytes));
  core::store_le32(b, kOffSequence, sequence);
  core::store_le32(b, kOffScan, pose.scan_sequence);
  core::store_le64(b, kOffStamp, static_cast<std::uint64_t>(pose.stamp_ns));
  for (int i = 0; i < 3; ++i) {
    core::store_le_f64(b, kOffPosition + 8 * static_cast<std::size_t>(i), pose.position[i]);
  }
  const Eigen::Quaterniond q = pose.orientation.normalized();
  const double qv[4] = {q.x(), q.y(), q.z(), q.w()};
  for (std::size_t i = 0; i < 4; ++i) core::store_le_f64(b, kOffQuaternion + 8 * i, qv[i]);
  core::store_le_f32(b, kOffCm, static_cast<float>(pose.cm));
  b[kOffStatus] = static_cast<std::uint8_t>(pose.status);
  b[kOffReserved] = 0;
  core::store_le16(b, kOffFlags, pose.flags);
  core::store_le32(b, kOffPoints, pose.points);
  core::store_le32(b, kOffCrc, crc32_ieee(core::ByteSpan(d).first(kOffCrc)));
  return d;
}

const char* to_string(DatagramError error) noexcept {
  switch (error) {
    case DatagramError::kNone:
      return "ok";
    case DatagramError::kSize:
      return "wrong size";
    case DatagramError::kMagic:
      return "not a cndt pose datagram (magic)";
    case DatagramError::kVersion:
      return "unsupported version";
    case DatagramError::kCrc:
      return "CRC mismatch";
    case DatagramError::kStatus:
      return "invalid status value";
  }
  return "unknown";
}

DecodedDatagram decode_pose_datagram(core::ByteSpan b) noexcept {
  DecodedDatagram out;
  if (b.size() < 8) {
    out.error = DatagramError::kSize;
    return out;
  }
  for (std::size_t i = 0; i < kMagic.size(); ++i) {
    if (b[i] != kMagic[i]) {
      out.error = DatagramError::kMagic;
      return out;
    }
  }
  if (core::load_le16(b, kOffVersion) != kPoseDatagramVersion) {
    out.error = DatagramError::kVersion;
    return out;
  }
  if (b.size() != kPoseDatagramBytes || core::load_le16(b, kOffSize) != kPoseDatagramBytes) {
    out.error = DatagramError::kSize;
    return out;
  }
  if (core::load_le32(b, kOffCrc) != crc32_ieee(b.first(kOffCrc))) {
    out.error = DatagramError::kCrc;
    return out;
  }
  if (b[kOffStatus] > static_cast<std::uint8_t>(PoseStatus::kLost)) {
    out.error = DatagramError::kStatus;
    return out;
  }
  out.sequence = core::load_le32(b, kOffSequence);
  PoseMessage& m = out.pose;
  m.stamp_ns = static_cast<std::int64_t>(core::load_le64(b, kOffStamp));
  for (int i = 0; i < 3; ++i) {
    m.position[i] = core::load_le_f64(b, kOffPosition + 8 * static_cast<std::size_t>(i));
  }
  m.orientation = Eigen::Quaterniond(
      core::load_le_f64(b, kOffQuaternion + 24), core::load_le_f64(b, kOffQuaternion),
      core::load_le_f64(b, kOffQuaternion + 8), core::load_le_f64(b, kOffQuaternion + 16));
  m.cm = core::load_le_f32(b, kOffCm);
  m.status = static_cast<PoseStatus>(b[kOffStatus]);
  m.flags = core::load_le16(b, kOffFlags);
  m.scan_sequence = core::load_le32(b, kOffScan);
  m.points = core::load_le32(b, kOffPoints);
  return out;
}

}  // namespace cndt::output
