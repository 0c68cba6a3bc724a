// Decodes one validated data packet into points in the sensor frame (REP-103), each with its own
// firing time, plus the list of firing sequences the scan assembler cuts on.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "cndt/core/bytes.hpp"
#include "cndt/core/scan.hpp"
#include "cndt/vlp16/calibration.hpp"
#include "cndt/vlp16/packet.hpp"

namespace cndt::vlp16 {

struct DecoderOptions {
  double min_range_m = 0.4;      ///< returns nearer than this are dropped (sensor minimum ~0.5 m)
  double max_range_m = 130.0;    ///< returns farther than this are dropped
  bool vertical_offsets = true;  ///< add each laser's vertical offset (manual table 9-1) to z
  bool simd = true;  ///< use the AVX2 kernel when the CPU has it (same results, within 1e-6)
};

/// One firing sequence: every laser fired once, in about 37 us.
struct Firing {
  std::uint32_t offset_ns = 0;    ///< first firing after the packet timestamp
  std::uint16_t azimuth = 0;      ///< rotor azimuth at the first firing, 0.01 deg, [0, 36000)
  std::uint16_t first_point = 0;  ///< index of its first point in DecodedPacket::points
  std::uint16_t point_count = 0;  ///< returns kept from this firing (zero and out-of-range dropped)
};

inline constexpr int kMaxFiringsPerPacket = 24;
inline constexpr int kMaxPointsPerPacket = 384;

/// A decoded packet. Point::time_ns holds the offset from the packet timestamp here; the scan
/// assembler rebases it onto the scan's stamp.
struct DecodedPacket {
  PacketHeader header;
  int firing_count = 0;
  int point_count = 0;
  std::array<Firing, kMaxFiringsPerPacket> firings{};
  std::array<core::Point, kMaxPointsPerPacket> points{};
};

class Decoder {
 public:
  Decoder(Model model, const DecoderOptions& options);

  [[nodiscard]] Model model() const noexcept { return table_.model; }
  [[nodiscard]] const LaserTable& table() const noexcept { return table_; }

  /// Decodes a packet that validate_data_packet() accepted with `header`. Never fails.
  void decode(core::ByteSpan payload, const PacketHeader& header,
              DecodedPacket& out) const noexcept;

 private:
  static constexpr std::size_t kRecordsPerBlock = 32;  // 3 bytes each: distance, reflectivity

  // Rotor angle of a block's first firing, its step per firing sequence, and its time.
  struct BlockAzimuth {
    float cos = 1.0F, sin = 0.0F;
    float step = 0.0F;  // radians per firing sequence
    std::uint32_t offset_ns = 0;
  };
  // One block's 32 records in the sensor frame.
  struct BlockPoints {
    std::array<float, kRecordsPerBlock> x, y, z, intensity;
    std::array<std::uint32_t, kRecordsPerBlock> count, valid;
  };
  void block_geometry(core::ByteSpan payload, std::size_t block, const BlockAzimuth& a,
                      BlockPoints& __restrict p) const noexcept;
  void decode_portable(core::ByteSpan payload,
                       const std::array<BlockAzimuth, kBlocksPerPacket>& blocks, bool dual,
                       DecodedPacket& out) const noexcept;
  void decode_avx2(core::ByteSpan payload, const std::array<BlockAzimuth, kBlocksPerPacket>& blocks,
                   bool dual, DecodedPacket& out) const noexcept;

  const LaserTable& table_;
  DecoderOptions options_;
  float range_unit_;
  std::uint32_t sequence_ns_;
  // Per-laser constants in the order of a block's records (laser, or sequence and laser).
  struct RecordTables {
    alignas(32) std::array<float, kRecordsPerBlock> cos_el, sin_el, z_offset, cos_az, sin_az;
    alignas(32) std::array<float, kRecordsPerBlock> phase;  // firing time in sequence periods
    std::array<std::uint64_t, kRecordsPerBlock> tail;       // time_ns | ring << 32
  };
  RecordTables records_{};
  bool avx2_ = false;                                 // the CPU runs decode_avx2()
  std::uint32_t min_count_u_ = 1, count_span_u_ = 0;  // valid counts: [min, min + span]
  std::vector<float> cos_table_, sin_table_;          // by azimuth in 0.01 deg
};

}  // namespace cndt::vlp16
