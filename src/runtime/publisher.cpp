#include "cndt/runtime/publisher.hpp"

#include <algorithm>
#include <cmath>

#include "cndt/output/udp_codec.hpp"

namespace cndt::runtime {

output::PoseMessage make_pose_message(const slam::OdometryResult& r, const Eigen::Isometry3d& pose,
                                      bool map_corrected, std::uint32_t scan_sequence,
                                      const PublisherOptions& options) noexcept {
  output::PoseMessage m;
  m.stamp_ns = r.stamp.count();
  m.scan_sequence = scan_sequence;
  m.position = pose.translation();
  m.orientation = Eigen::Quaterniond(pose.linear()).normalized();
  m.cm = std::isfinite(r.cm) ? std::clamp(r.cm, 0.0, 1.0) : 0.0;
  m.points = static_cast<std::uint32_t>(std::min<std::size_t>(r.points, 0xFFFFFFFFu));
  std::uint16_t f = 0;
  if (map_corrected) f |= output::kPoseMapCorrected;
  if ((r.flags & slam::kOdomNotConverged) != 0) f |= output::kPoseNotConverged;
  if ((r.flags & slam::kOdomTooFewPoints) != 0) f |= output::kPoseTooFewPoints;
  if ((r.flags & slam::kOdomDegenerate) != 0) f |= output::kPoseDegenerate;
  if ((r.flags & slam::kOdomScanIncomplete) != 0) f |= output::kPoseScanIncomplete;
  if ((r.flags & slam::kOdomFirstScan) != 0) f |= output::kPoseFirstScan;
  if ((r.flags & slam::kOdomCmUnmeasured) != 0) f |= output::kPoseCmUnmeasured;
  m.flags = f;
  if ((r.flags & (slam::kOdomTooFewPoints | slam::kOdomDegenerate)) != 0) {
    m.status = output::PoseStatus::kLost;
  } else if ((r.flags & slam::kOdomFirstScan) != 0) {
    m.status = output::PoseStatus::kValid;  // the origin, by definition
  } else if (m.cm < options.degraded_below_cm ||
             (r.flags &
              (slam::kOdomNotConverged | slam::kOdomRematched | slam::kOdomShortOfPyramid)) != 0) {
    m.status = output::PoseStatus::kDegraded;
  } else {
    m.status = output::PoseStatus::kValid;
  }
  return m;
}

void PosePublisher::publish(const output::PoseMessage& m) noexcept {
  ++stats_.poses;
  switch (m.status) {
    case output::PoseStatus::kValid:
      ++stats_.valid;
      break;
    case output::PoseStatus::kDegraded:
      ++stats_.degraded;
      break;
    case output::PoseStatus::kLost:
      ++stats_.lost;
      break;
  }
  if (!can_.empty()) {
    const auto frames =
        output::encode_pose_frames(m, counter_, options_.can_base_id, options_.can_extended);
    const auto stamp = std::chrono::nanoseconds(m.stamp_ns);
    for (auto& bus : can_) {
      for (const auto& f : frames) bus->send(f, stamp);
      bus->flush();
    }
  }
  counter_ = static_cast<std::uint8_t>((counter_ + 1) & 0x0Fu);
  if (!udp_.empty()) {
    const auto d = output::encode_pose_datagram(m, sequence_);
    for (auto& u : udp_) u->send(d);
  }
  ++sequence_;
}

void PosePublisher::flush() noexcept {
  for (auto& bus : can_) bus->flush();
}

}  // namespace cndt::runtime
