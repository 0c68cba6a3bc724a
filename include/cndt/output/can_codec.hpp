// The pose as classic 8-byte CAN frames: the layout config/cndt.dbc describes. Five frames per
// pose, ids base+0..base+4 (base 0x300 by default), all signals little-endian (Intel):
//
//   base+0 CNDT_Status       Status 12|2, MapCorrected 14|1, OutOfRange 15|1, Cm 16|16 x 1e-4,
//                            ScanSeq 32|16, Points 48|16
//   base+1 CNDT_Time         TimeUs 12|20 (0..999999 us), TimeS 32|32 (s since the Unix epoch)
//   base+2 CNDT_PositionXY   X 12|26 signed x 1 mm, Y 38|26 signed x 1 mm
//   base+3 CNDT_PositionZ    Z 12|26 signed x 1 mm
//   base+4 CNDT_Orientation  Roll 16|16, Pitch 32|16, Yaw 48|16 signed x 1e-4 rad
//                            (R = Rz(yaw) Ry(pitch) Rx(roll))
//
// Every frame: byte 0 is a CRC-8 SAE J1850 over bytes 1..7; the low nibble of byte 1 is a rolling
// counter 0..15 that advances by one per pose and is the same in the five frames of one pose, so
// a receiver groups them and sees lost, repeated and stale frames.
#pragma once

#include <array>
#include <cstdint>
#include <optional>

#include "cndt/output/pose_message.hpp"

namespace cndt::output {

struct CanFrame {
  std::uint32_t id = 0;  ///< 11-bit standard id (or 29-bit with extended)
  bool extended = false;
  std::uint8_t len = 8;
  std::array<std::uint8_t, 8> data{};
};

inline constexpr std::size_t kCanFramesPerPose = 5;
inline constexpr std::uint32_t kDefaultCanBaseId = 0x300;
enum CanFrameIndex : std::uint32_t {
  kCanStatus = 0,
  kCanTime = 1,
  kCanPositionXY = 2,
  kCanPositionZ = 3,
  kCanOrientation = 4,
};

/// Resolutions (one raw step) of the signals.
inline constexpr double kCanPositionStep = 0.001;  ///< m
inline constexpr double kCanAngleStep = 1e-4;      ///< rad
inline constexpr double kCanCmStep = 1e-4;

using CanPoseFrames = std::array<CanFrame, kCanFramesPerPose>;

/// The five frames of one pose. `counter` is taken modulo 16. Values beyond a signal's range
/// are clamped and OutOfRange is set. Allocation-free.
CanPoseFrames encode_pose_frames(const PoseMessage& pose, std::uint8_t counter,
                                 std::uint32_t base_id = kDefaultCanBaseId,
                                 bool extended = false) noexcept;

/// Whether the frame's CRC byte matches bytes 1..7.
bool can_crc_ok(const CanFrame& frame) noexcept;

struct CanDecodeStats {
  std::uint64_t frames = 0;            ///< frames with one of our ids
  std::uint64_t bad_length = 0;        ///< not 8 bytes: refused
  std::uint64_t bad_crc = 0;           ///< refused
  std::uint64_t counter_gaps = 0;      ///< a frame id's counter skipped values (frames lost)
  std::uint64_t counter_repeats = 0;   ///< a frame id's counter did not advance (stale frame)
  std::uint64_t incomplete_poses = 0;  ///< a pose whose five frames did not all arrive
  std::uint64_t poses = 0;
};

/// Reassembles poses from frames (in any order within one pose), checking CRCs and counters.
class CanPoseDecoder {
 public:
  explicit CanPoseDecoder(std::uint32_t base_id = kDefaultCanBaseId) : base_id_(base_id) {}
  /// Feeds one frame; returns the pose once its five frames have arrived. Frames with other ids
  /// are ignored.
  std::optional<PoseMessage> feed(const CanFrame& frame);
  [[nodiscard]] const CanDecodeStats& stats() const { return stats_; }
  /// Counts a pose still being assembled as incomplete (call at the end of the input).
  void finish();

 private:
  std::uint32_t base_id_;
  CanDecodeStats stats_;
  std::array<int, kCanFramesPerPose> last_counter_{-1, -1, -1, -1, -1};
  int group_counter_ = -1;
  std::uint32_t group_mask_ = 0;
  std::array<CanFrame, kCanFramesPerPose> group_{};
};

}  // namespace cndt::output
