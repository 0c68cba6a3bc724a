#include "cndt/vlp16/decoder.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstring>
#include <numbers>

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#define CNDT_DECODER_AVX2 1
#include <immintrin.h>
#endif

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
  // Per-laser constants in record order: a block's 32 records are 32 lasers of one sequence, or
  // 16 lasers of two sequences.
  const auto lasers = static_cast<std::size_t>(table_.lasers);
  for (std::size_t j = 0; j < kRecordsPerBlock; ++j) {
    const std::size_t k = j % lasers;
    const std::size_t sub = j / lasers;
    const double el = table_.elevation_deg[k] * std::numbers::pi / 180.0;
    const double az = table_.azimuth_offset_deg[k] * std::numbers::pi / 180.0;
    const double t_us = table_.laser_offset_us(static_cast<int>(k));
    records_.cos_el[j] = static_cast<float>(std::cos(el));
    records_.sin_el[j] = static_cast<float>(std::sin(el));
    records_.z_offset[j] =
        options_.vertical_offsets ? static_cast<float>(table_.vertical_offset_m[k]) : 0.0F;
    records_.cos_az[j] = static_cast<float>(std::cos(az));
    records_.sin_az[j] = static_cast<float>(std::sin(az));
    records_.phase[j] =
        static_cast<float>(sub) + static_cast<float>(t_us / table_.sequence_period_us);
    // The point's last 8 bytes: time after the packet stamp, ring << 32.
    const auto time_ns =
        static_cast<std::uint64_t>(std::lround(t_us * 1000.0)) + sub * sequence_ns_;
    records_.tail[j] = time_ns | (static_cast<std::uint64_t>(table_.ring[k]) << 32);
  }
  // Range limits in distance counts (rounded to float first, as the limits always were). A count
  // of 0 means no return: the lower limit is at least one count.
  const auto min_count =
      std::max(1.0F, static_cast<float>(options_.min_range_m / table_.range_unit_m));
  const auto max_count = static_cast<float>(options_.max_range_m / table_.range_unit_m);
  min_count_u_ = static_cast<std::uint32_t>(std::ceil(min_count));
  count_span_u_ =
      static_cast<std::uint32_t>(std::floor(std::min(max_count, 65535.0F))) - min_count_u_;
#if CNDT_DECODER_AVX2
  avx2_ = options_.simd && __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
#endif
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

  // Firing sequences: the block azimuth, the second sequence of a block interpolated halfway to
  // the next block's.
  const int seqs = table_.sequences_per_block;
  std::array<BlockAzimuth, kBlocksPerPacket> blocks{};
  for (int g = 0; g < groups; ++g) {
    const auto gi = static_cast<std::size_t>(g);
    const double per_sequence = static_cast<double>(gap[gi]) / seqs;
    for (int s = 0; s < seqs; ++s) {
      Firing& f = out.firings[static_cast<std::size_t>(g * seqs + s)];
      f.offset_ns = static_cast<std::uint32_t>(g * seqs + s) * sequence_ns_;
      f.azimuth = static_cast<std::uint16_t>(
          static_cast<int>(azimuth[gi] + per_sequence * s + 0.5) % 36000);
    }
    for (int b = g * group; b < (g + 1) * group; ++b) {
      BlockAzimuth& a = blocks[static_cast<std::size_t>(b)];
      a.cos = cos_table_[static_cast<std::size_t>(azimuth[gi])];
      a.sin = sin_table_[static_cast<std::size_t>(azimuth[gi])];
      a.step = static_cast<float>(per_sequence * kCdegToRad);
      a.offset_ns = static_cast<std::uint32_t>(g * seqs) * sequence_ns_;
    }
  }
  out.firing_count = groups * seqs;

#if CNDT_DECODER_AVX2
  if (avx2_) {
    decode_avx2(payload, blocks, dual, out);
    return;
  }
#endif
  decode_portable(payload, blocks, dual, out);
}

void Decoder::block_geometry(core::ByteSpan payload, std::size_t block, const BlockAzimuth& a,
                             BlockPoints& __restrict p) const noexcept {
  const std::size_t off = block * kBlockSize + 4;
  // Four records (12 bytes) from three 32-bit words: byte gathers would be assembled into
  // vectors through memory and stall.
  for (std::size_t q = 0; q < kRecordsPerBlock / 4; ++q) {
    const std::uint32_t w0 = core::load_le32(payload, off + 12 * q);
    const std::uint32_t w1 = core::load_le32(payload, off + 12 * q + 4);
    const std::uint32_t w2 = core::load_le32(payload, off + 12 * q + 8);
    const std::size_t j = 4 * q;
    p.count[j] = w0 & 0xFFFFU;
    p.count[j + 1] = (w0 >> 24) | ((w1 & 0xFFU) << 8);
    p.count[j + 2] = w1 >> 16;
    p.count[j + 3] = (w2 >> 8) & 0xFFFFU;
    p.intensity[j] = static_cast<float>(static_cast<std::int32_t>((w0 >> 16) & 0xFFU));
    p.intensity[j + 1] = static_cast<float>(static_cast<std::int32_t>((w1 >> 8) & 0xFFU));
    p.intensity[j + 2] = static_cast<float>(static_cast<std::int32_t>(w2 & 0xFFU));
    p.intensity[j + 3] = static_cast<float>(static_cast<std::int32_t>(w2 >> 24));
  }
  for (std::size_t j = 0; j < kRecordsPerBlock; ++j) {
    // The block azimuth turned by the step to this record's firing (third order: the step is
    // below 1 deg at 1200 rpm, and the sine and cosine stay within 1e-5 rad up to 15 deg), then by
    // the laser's own azimuth offset (VLP-32C).
    const float d = a.step * records_.phase[j];
    const float d2 = d * d;
    const float cd = 1.0F - d2 * (0.5F - d2 * (1.0F / 24.0F));
    const float sd = d - d * d2 * (1.0F / 6.0F);
    const float c = a.cos * cd - a.sin * sd;
    const float sn = a.sin * cd + a.cos * sd;
    const float ca = c * records_.cos_az[j] - sn * records_.sin_az[j];
    const float sa = sn * records_.cos_az[j] + c * records_.sin_az[j];
    // Counts fit in 16 bits: converted as signed, one instruction.
    const float r = static_cast<float>(static_cast<std::int32_t>(p.count[j])) * range_unit_;
    const float xy = r * records_.cos_el[j];
    p.x[j] = xy * ca;
    p.y[j] = -xy * sa;  // the sensor's azimuth runs clockwise seen from above
    p.z[j] = r * records_.sin_el[j] + records_.z_offset[j];
    // In range when min <= count <= max: one unsigned comparison.
    p.valid[j] = (p.count[j] - min_count_u_) <= count_span_u_ ? 1U : 0U;
  }
}

namespace {
constexpr std::uint64_t type_tag(core::ReturnType t) noexcept {
  return std::uint64_t{static_cast<std::uint8_t>(t)} << 48;
}

// Writes one point as two wide stores (x y z intensity, then time ring type reserved: the layout
// static_asserted in scan.hpp) into the next free slot, which is kept only when `keep` is 1.
inline void put_point(unsigned char* points, std::size_t& np, const float* head, std::uint64_t tail,
                      std::uint32_t keep) noexcept {
  unsigned char* dst = points + np * sizeof(core::Point);
  std::memcpy(dst, head, 4 * sizeof(float));
  std::memcpy(dst + offsetof(core::Point, time_ns), &tail, sizeof tail);
  np += keep;
}
}  // namespace

void Decoder::decode_portable(core::ByteSpan payload,
                              const std::array<BlockAzimuth, kBlocksPerPacket>& blocks, bool dual,
                              DecodedPacket& out) const noexcept {
  auto* const points = reinterpret_cast<unsigned char*>(out.points.data());
  const auto lasers = static_cast<std::size_t>(table_.lasers);
  std::size_t np = 0;
  BlockPoints a, b;
  auto head = [](const BlockPoints& p, std::size_t j) {
    return std::array<float, 4>{p.x[j], p.y[j], p.z[j], p.intensity[j]};
  };
  const std::size_t step = dual ? 2 : 1;
  std::size_t q = 0;  // firing sequence
  for (std::size_t blk = 0; blk < kBlocksPerPacket; blk += step) {
    block_geometry(payload, blk, blocks[blk], a);
    if (dual) block_geometry(payload, blk + 1, blocks[blk + 1], b);
    const std::uint64_t offset = blocks[blk].offset_ns;
    for (std::size_t first = 0; first < kRecordsPerBlock; first += lasers, ++q) {
      Firing& f = out.firings[q];
      f.first_point = static_cast<std::uint16_t>(np);
      for (std::size_t j = first; j < first + lasers; ++j) {
        const std::uint64_t tail = records_.tail[j] + offset;
        if (!dual) {
          put_point(points, np, head(a, j).data(), tail, a.valid[j]);
        } else {
          // The even block holds the last return, the odd block the strongest (or second
          // strongest). Identical records mean a single return: kept once.
          const bool same = a.count[j] == b.count[j] && a.intensity[j] == b.intensity[j];
          put_point(points, np, head(a, j).data(),
                    tail | type_tag(same ? core::ReturnType::kBoth : core::ReturnType::kLast),
                    a.valid[j]);
          put_point(points, np, head(b, j).data(), tail | type_tag(core::ReturnType::kStrongest),
                    same ? 0U : b.valid[j]);
        }
      }
      f.point_count = static_cast<std::uint16_t>(np - f.first_point);
    }
  }
  out.point_count = static_cast<int>(np);
}

#if CNDT_DECODER_AVX2
namespace {
#define CNDT_AVX2_INLINE __attribute__((target("avx2,fma"), always_inline)) inline

// Eight consecutive records of a block as points, one per 128-bit lane (x y z intensity).
struct Eight {
  __m256 p[4];     // points 0|4, 1|5, 2|6, 3|7
  unsigned valid;  // bit k: record k in range
};

struct EightTables {
  const float *phase, *cos_az, *sin_az, *cos_el, *sin_el, *z_offset;
};

CNDT_AVX2_INLINE Eight eight_points(const std::uint8_t* src, float cos0, float sin0, float step,
                                    const EightTables& t, float range_unit, int min_count,
                                    int max_count) {
  // Four 3-byte records per 128-bit lane: the distance as a 32-bit integer, the reflectivity.
  const __m256i count_shuffle =
      _mm256_setr_epi8(0, 1, -1, -1, 3, 4, -1, -1, 6, 7, -1, -1, 9, 10, -1, -1,  //
                       0, 1, -1, -1, 3, 4, -1, -1, 6, 7, -1, -1, 9, 10, -1, -1);
  const __m256i refl_shuffle =
      _mm256_setr_epi8(2, -1, -1, -1, 5, -1, -1, -1, 8, -1, -1, -1, 11, -1, -1, -1,  //
                       2, -1, -1, -1, 5, -1, -1, -1, 8, -1, -1, -1, 11, -1, -1, -1);
  Eight e;
  // Records 0..3 and 4..7; in the last block the read ends 2 bytes before the packet does.
  const __m128i lo = _mm_loadu_si128(reinterpret_cast<const __m128i*>(src));
  const __m128i hi = _mm_loadu_si128(reinterpret_cast<const __m128i*>(src + 12));
  const __m256i v = _mm256_inserti128_si256(_mm256_castsi128_si256(lo), hi, 1);
  const __m256i count = _mm256_shuffle_epi8(v, count_shuffle);
  const __m256 intensity = _mm256_cvtepi32_ps(_mm256_shuffle_epi8(v, refl_shuffle));
  const __m256i ok = _mm256_and_si256(_mm256_cmpgt_epi32(count, _mm256_set1_epi32(min_count - 1)),
                                      _mm256_cmpgt_epi32(_mm256_set1_epi32(max_count + 1), count));
  e.valid = static_cast<unsigned>(_mm256_movemask_ps(_mm256_castsi256_ps(ok)));

  const __m256 d = _mm256_mul_ps(_mm256_set1_ps(step), _mm256_load_ps(t.phase));
  const __m256 d2 = _mm256_mul_ps(d, d);
  const __m256 cd =
      _mm256_fnmadd_ps(d2, _mm256_fnmadd_ps(d2, _mm256_set1_ps(1.0F / 24.0F), _mm256_set1_ps(0.5F)),
                       _mm256_set1_ps(1.0F));
  const __m256 sd = _mm256_fnmadd_ps(_mm256_mul_ps(d, d2), _mm256_set1_ps(1.0F / 6.0F), d);
  const __m256 c0 = _mm256_set1_ps(cos0), s0 = _mm256_set1_ps(sin0);
  const __m256 c = _mm256_fmsub_ps(c0, cd, _mm256_mul_ps(s0, sd));
  const __m256 sn = _mm256_fmadd_ps(s0, cd, _mm256_mul_ps(c0, sd));
  const __m256 caz = _mm256_load_ps(t.cos_az), saz = _mm256_load_ps(t.sin_az);
  const __m256 ca = _mm256_fmsub_ps(c, caz, _mm256_mul_ps(sn, saz));
  const __m256 sa = _mm256_fmadd_ps(sn, caz, _mm256_mul_ps(c, saz));
  const __m256 r = _mm256_mul_ps(_mm256_cvtepi32_ps(count), _mm256_set1_ps(range_unit));
  const __m256 xy = _mm256_mul_ps(r, _mm256_load_ps(t.cos_el));
  const __m256 x = _mm256_mul_ps(xy, ca);
  const __m256 y = _mm256_xor_ps(_mm256_mul_ps(xy, sa), _mm256_set1_ps(-0.0F));
  const __m256 z = _mm256_fmadd_ps(r, _mm256_load_ps(t.sin_el), _mm256_load_ps(t.z_offset));
  // Transpose to one point per 128-bit lane.
  const __m256 xy_lo = _mm256_unpacklo_ps(x, y), xy_hi = _mm256_unpackhi_ps(x, y);
  const __m256 zi_lo = _mm256_unpacklo_ps(z, intensity);
  const __m256 zi_hi = _mm256_unpackhi_ps(z, intensity);
  e.p[0] = _mm256_shuffle_ps(xy_lo, zi_lo, 0x44);
  e.p[1] = _mm256_shuffle_ps(xy_lo, zi_lo, 0xEE);
  e.p[2] = _mm256_shuffle_ps(xy_hi, zi_hi, 0x44);
  e.p[3] = _mm256_shuffle_ps(xy_hi, zi_hi, 0xEE);
  return e;
}

// Point k of eight as x y z intensity, then its tail, into the next free slot (kept if `keep`).
CNDT_AVX2_INLINE void put_eight(unsigned char* points, std::size_t& np, const Eight& e,
                                std::size_t k, std::uint64_t tail, unsigned keep) {
  const __m128 h = k < 4 ? _mm256_castps256_ps128(e.p[k]) : _mm256_extractf128_ps(e.p[k - 4], 1);
  unsigned char* dst = points + np * sizeof(core::Point);
  _mm_storeu_ps(reinterpret_cast<float*>(dst), h);
  std::memcpy(dst + offsetof(core::Point, time_ns), &tail, sizeof tail);
  np += keep;
}
#undef CNDT_AVX2_INLINE
}  // namespace

// The arithmetic of block_geometry() and decode_portable(), eight records at a time.
__attribute__((target("avx2,fma"))) void Decoder::decode_avx2(
    core::ByteSpan payload, const std::array<BlockAzimuth, kBlocksPerPacket>& blocks, bool dual,
    DecodedPacket& out) const noexcept {
  auto* const points = reinterpret_cast<unsigned char*>(out.points.data());
  const std::uint8_t* const bytes = payload.data();
  const auto lasers = static_cast<std::size_t>(table_.lasers);
  const int min_count = static_cast<int>(min_count_u_);
  const int max_count = static_cast<int>(min_count_u_ + count_span_u_);

  std::size_t np = 0;
  const std::size_t step = dual ? 2 : 1;
  std::size_t q = 0;  // firing sequence
  for (std::size_t blk = 0; blk < kBlocksPerPacket; blk += step) {
    const std::uint64_t offset = blocks[blk].offset_ns;
    for (std::size_t j = 0; j < kRecordsPerBlock; j += 8) {
      if (j % lasers == 0) out.firings[q].first_point = static_cast<std::uint16_t>(np);
      const EightTables t{&records_.phase[j],  &records_.cos_az[j], &records_.sin_az[j],
                          &records_.cos_el[j], &records_.sin_el[j], &records_.z_offset[j]};
      const std::uint8_t* src = bytes + blk * kBlockSize + 4 + 3 * j;
      const BlockAzimuth& az = blocks[blk];
      const Eight a =
          eight_points(src, az.cos, az.sin, az.step, t, range_unit_, min_count, max_count);
      if (!dual) {
        for (std::size_t k = 0; k < 8; ++k) {
          put_eight(points, np, a, k, records_.tail[j + k] + offset, (a.valid >> k) & 1U);
        }
      } else {
        const BlockAzimuth& bz = blocks[blk + 1];
        const std::uint8_t* pair = src + kBlockSize;
        const Eight b =
            eight_points(pair, bz.cos, bz.sin, bz.step, t, range_unit_, min_count, max_count);
        // Identical records (distance and reflectivity) are one return, kept once.
        unsigned same = 0;
        for (std::size_t k = 0; k < 8; ++k) {
          same |= (std::memcmp(src + 3 * k, pair + 3 * k, 3) == 0 ? 1U : 0U) << k;
        }
        for (std::size_t k = 0; k < 8; ++k) {
          const std::uint64_t tail = records_.tail[j + k] + offset;
          const bool s = ((same >> k) & 1U) != 0;
          put_eight(points, np, a, k,
                    tail | type_tag(s ? core::ReturnType::kBoth : core::ReturnType::kLast),
                    (a.valid >> k) & 1U);
          put_eight(points, np, b, k, tail | type_tag(core::ReturnType::kStrongest),
                    s ? 0U : (b.valid >> k) & 1U);
        }
      }
      if ((j + 8) % lasers == 0) {
        out.firings[q].point_count = static_cast<std::uint16_t>(np - out.firings[q].first_point);
        ++q;
      }
    }
  }
  out.point_count = static_cast<int>(np);
}
#endif

}  // namespace cndt::vlp16
