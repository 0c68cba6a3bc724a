#include "cndt/vlp16/decoder.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstring>
#include <numbers>

namespace cndt::vlp16 {
namespace {

constexpr double kCdegToRad = std::numbers::pi / 18000.0;
// A block-to-block azimuth step above 15 deg cannot come from a spinning sensor (1200 rpm gives
// 0.8 deg); such a step is a glitch and the neighbouring step is used instead.
constexpr int kMaxPlausibleGap = 1500;

}  // namespace

Decoder::Decoder(Model model, const DecoderOptions& options)
    : table_(laser_table(model)),
      options_(options),
      // A count of 0 means no return: the lower limit is at least one count.
      min_count_(std::max(
          1.0F, static_cast<float>(options.min_range_m / laser_table(model).range_unit_m))),
      max_count_(static_cast<float>(options.max_range_m / laser_table(model).range_unit_m)),
      range_unit_(static_cast<float>(laser_table(model).range_unit_m)),
      sequence_ns_(
          static_cast<std::uint32_t>(std::lround(laser_table(model).sequence_period_us * 1000.0))),
      cos_table_(36000),
      sin_table_(36000) {
  for (std::size_t i = 0; i < 36000; ++i) {
    const double a = static_cast<double>(i) * kCdegToRad;
    cos_table_[i] = static_cast<float>(std::cos(a));
    sin_table_[i] = static_cast<float>(std::sin(a));
  }
  for (int k = 0; k < table_.lasers; ++k) {
    const auto i = static_cast<std::size_t>(k);
    const double el = table_.elevation_deg[i] * std::numbers::pi / 180.0;
    const double az = table_.azimuth_offset_deg[i] * std::numbers::pi / 180.0;
    const double t_us = table_.laser_offset_us(k);
    cos_el_[i] = static_cast<float>(std::cos(el));
    sin_el_[i] = static_cast<float>(std::sin(el));
    z_offset_[i] =
        options_.vertical_offsets ? static_cast<float>(table_.vertical_offset_m[i]) : 0.0F;
    cos_az_off_[i] = static_cast<float>(std::cos(az));
    sin_az_off_[i] = static_cast<float>(std::sin(az));
    time_fraction_[i] = static_cast<float>(t_us / table_.sequence_period_us);
    time_ns_[i] = static_cast<std::uint32_t>(std::lround(t_us * 1000.0));
    ring_[i] = table_.ring[i];
    tail_[i] = time_ns_[i] | (static_cast<std::uint64_t>(ring_[i]) << 32);
  }
  min_count_u_ = static_cast<std::uint32_t>(std::ceil(min_count_));
  count_span_u_ =
      static_cast<std::uint32_t>(std::floor(std::min(max_count_, 65535.0F))) - min_count_u_;
}

void Decoder::decode(core::ByteSpan payload, const PacketHeader& header,
                     DecodedPacket& out) const noexcept {
  out.header = header;
  out.firing_count = 0;
  out.point_count = 0;
  const bool dual = header.mode == ReturnMode::kDual;
  const int group = dual ? 2 : 1;  // blocks per group: a dual-return pair shares its firings
  const int groups = kBlocksPerPacket / group;

  std::array<int, kBlocksPerPacket> azimuth{};
  for (int g = 0; g < groups; ++g) {
    azimuth[static_cast<std::size_t>(g)] =
        core::load_le16(payload, static_cast<std::size_t>(g * group) * kBlockSize + 2) % 36000;
  }
  // Azimuth advance from each group to the next, modulo one turn (the 35999 -> 0 wrap is normal).
  std::array<int, kBlocksPerPacket> gap{};
  int last_good = -1;
  for (int g = 0; g + 1 < groups; ++g) {
    const auto i = static_cast<std::size_t>(g);
    const int d = (azimuth[i + 1] - azimuth[i] + 36000) % 36000;
    gap[i] = d <= kMaxPlausibleGap ? d : -1;
    if (gap[i] >= 0) last_good = gap[i];
  }
  gap[static_cast<std::size_t>(groups - 1)] = -1;
  // The last group has no successor: reuse the previous step, as do implausible steps.
  int fill = last_good >= 0 ? last_good : 0;
  for (int g = 0; g < groups; ++g) {
    auto& v = gap[static_cast<std::size_t>(g)];
    if (v < 0) {
      v = fill;
    } else {
      fill = v;
    }
  }

  const int seqs = table_.sequences_per_block;
  const auto lasers = static_cast<std::size_t>(table_.lasers);
  for (int g = 0; g < groups; ++g) {
    const auto gi = static_cast<std::size_t>(g);
    const double per_sequence = static_cast<double>(gap[gi]) / seqs;
    const std::size_t block_off = static_cast<std::size_t>(g * group) * kBlockSize;
    for (int s = 0; s < seqs; ++s) {
      const std::size_t record_off = block_off + 4 + static_cast<std::size_t>(s) * lasers * 3;
      const std::size_t pair_off = dual ? record_off + kBlockSize : record_off;
      Firing& f = out.firings[static_cast<std::size_t>(out.firing_count)];
      f.offset_ns = static_cast<std::uint32_t>(g * seqs + s) * sequence_ns_;
      decode_sequence(payload, record_off, pair_off, dual, azimuth[gi] + per_sequence * s,
                      per_sequence, out);
      ++out.firing_count;
    }
  }
}

void Decoder::decode_sequence(core::ByteSpan payload, std::size_t record_off, std::size_t pair_off,
                              bool dual, double azimuth, double gap_per_sequence,
                              DecodedPacket& out) const noexcept {
  // The laser count and return mode as constants let the compiler unroll and vectorise.
  if (table_.lasers == 16) {
    if (dual) {
      decode_sequence_n<16, true>(payload, record_off, pair_off, azimuth, gap_per_sequence, out);
    } else {
      decode_sequence_n<16, false>(payload, record_off, pair_off, azimuth, gap_per_sequence, out);
    }
  } else if (dual) {
    decode_sequence_n<32, true>(payload, record_off, pair_off, azimuth, gap_per_sequence, out);
  } else {
    decode_sequence_n<32, false>(payload, record_off, pair_off, azimuth, gap_per_sequence, out);
  }
}

template <std::size_t N, bool Dual>
void Decoder::decode_sequence_n(core::ByteSpan payload, std::size_t record_off,
                                std::size_t pair_off, double azimuth, double gap_per_sequence,
                                DecodedPacket& out) const noexcept {
  Firing& f = out.firings[static_cast<std::size_t>(out.firing_count)];
  // azimuth is non-negative (block azimuth plus a forward step): truncation is floor.
  const int base_int = static_cast<int>(azimuth);
  const double base = base_int;
  const auto base_index = static_cast<std::size_t>(base_int % 36000);
  f.azimuth = static_cast<std::uint16_t>(static_cast<int>(azimuth + 0.5) % 36000);
  f.first_point = static_cast<std::uint16_t>(out.point_count);
  const float c0 = cos_table_[base_index];
  const float s0 = sin_table_[base_index];
  const auto frac = static_cast<float>(azimuth - base);
  const auto gap = static_cast<float>(gap_per_sequence);
  constexpr std::size_t n = N;

  // 1. Geometry of every laser's record, in plain array loops the compiler vectorises: the table
  // angle turned by the small interpolated step (< 1 deg, second order), then by the laser's own
  // azimuth offset (VLP-32C), then the point itself.
  std::array<float, N> ca, sa;  // written for every laser before any read
  for (std::size_t k = 0; k < n; ++k) {
    const float d = (frac + gap * time_fraction_[k]) * static_cast<float>(kCdegToRad);
    const float h = 1.0F - 0.5F * d * d;
    const float c = c0 * h - s0 * d;
    const float s = s0 * h + c0 * d;
    ca[k] = c * cos_az_off_[k] - s * sin_az_off_[k];
    sa[k] = s * cos_az_off_[k] + c * sin_az_off_[k];
  }
  struct Block {
    std::array<float, N> x, y, z;
    std::array<std::uint32_t, N> count;
  };
  auto geometry = [&](std::size_t off, Block& g) {
    for (std::size_t k = 0; k < n; ++k) g.count[k] = core::load_le16(payload, off + 3 * k);
    for (std::size_t k = 0; k < n; ++k) {
      const float r = static_cast<float>(g.count[k]) * range_unit_;
      const float xy = r * cos_el_[k];
      g.x[k] = xy * ca[k];
      g.y[k] = -xy * sa[k];  // the sensor's azimuth runs clockwise seen from above
      g.z[k] = r * sin_el_[k] + z_offset_[k];
    }
  };
  // 2. Returns, written without branches: each candidate goes to the next free slot, which is
  // kept only when the return is valid.
  int np = out.point_count;  // in a register: the point stores could alias the member
  const std::uint64_t offset = f.offset_ns;
  auto put = [&](const Block& g, std::size_t k, std::uint8_t refl, core::ReturnType type,
                 bool keep) {
    // In range when min <= count <= max: one unsigned comparison.
    const bool valid = keep && (g.count[k] - min_count_u_) <= count_span_u_;
    // Two wide stores per point instead of eight narrow ones: x y z intensity, then
    // time ring type reserved (the layout static_asserted in scan.hpp).
    const float head[4] = {g.x[k], g.y[k], g.z[k], static_cast<float>(refl)};
    const std::uint64_t tail =
        tail_[k] + offset + (static_cast<std::uint64_t>(static_cast<std::uint8_t>(type)) << 48);
    auto* dst = reinterpret_cast<unsigned char*>(&out.points[static_cast<std::size_t>(np)]);
    std::memcpy(dst, head, sizeof head);
    std::memcpy(dst + offsetof(core::Point, time_ns), &tail, sizeof tail);
    np += valid ? 1 : 0;
  };
  Block first;
  geometry(record_off, first);
  if constexpr (!Dual) {
    for (std::size_t k = 0; k < n; ++k) {
      put(first, k, payload[record_off + 3 * k + 2], core::ReturnType::kSingle, true);
    }
  } else {
    // The even block holds the last return, the odd block the strongest (or second strongest).
    // Identical records mean a single return: kept once.
    Block second;
    geometry(pair_off, second);
    for (std::size_t k = 0; k < n; ++k) {
      const std::size_t a = record_off + 3 * k, b = pair_off + 3 * k;
      const bool same = payload[a] == payload[b] && payload[a + 1] == payload[b + 1] &&
                        payload[a + 2] == payload[b + 2];
      put(first, k, payload[a + 2], same ? core::ReturnType::kBoth : core::ReturnType::kLast, true);
      put(second, k, payload[b + 2], core::ReturnType::kStrongest, !same);
    }
  }
  out.point_count = np;
  f.point_count = static_cast<std::uint16_t>(out.point_count - f.first_point);
}

}  // namespace cndt::vlp16
