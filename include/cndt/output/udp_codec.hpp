// The pose as one UDP datagram, little-endian, 96 bytes (docs/protocol.md, byte by byte):
//
//   0  u8[4] magic "CNDP"            48 f64 qx
//   4  u16   version (1)             56 f64 qy
//   6  u16   datagram size (96)      64 f64 qz
//   8  u32   datagram sequence       72 f64 qw
//  12  u32   scan sequence           80 f32 Cm
//  16  i64   scan time, ns (Unix)    84 u8  status (0 valid, 1 degraded, 2 lost)
//  24  f64   x, m                    85 u8  reserved (0)
//  32  f64   y, m                    86 u16 flags (PoseFlags)
//  40  f64   z, m                    88 u32 points matched
//                                    92 u32 CRC-32 (IEEE) of bytes 0..91
#pragma once

#include <array>
#include <cstdint>
#include <string>

#include "cndt/core/bytes.hpp"
#include "cndt/output/pose_message.hpp"

namespace cndt::output {

inline constexpr std::size_t kPoseDatagramBytes = 96;
inline constexpr std::uint16_t kPoseDatagramVersion = 1;
using PoseDatagram = std::array<std::uint8_t, kPoseDatagramBytes>;

/// Encodes one pose; `sequence` counts datagrams from 0. Allocation-free.
PoseDatagram encode_pose_datagram(const PoseMessage& pose, std::uint32_t sequence) noexcept;

enum class DatagramError : std::uint8_t { kNone, kSize, kMagic, kVersion, kCrc, kStatus };
const char* to_string(DatagramError error) noexcept;

struct DecodedDatagram {
  DatagramError error = DatagramError::kNone;
  std::uint32_t sequence = 0;
  PoseMessage pose;
};

/// Decodes and checks one datagram (size, magic, version, CRC, status value).
DecodedDatagram decode_pose_datagram(core::ByteSpan bytes) noexcept;

}  // namespace cndt::output
