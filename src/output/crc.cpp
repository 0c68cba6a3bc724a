#include "cndt/output/crc.hpp"

#include <array>
#include <boost/crc.hpp>

namespace cndt::output {
namespace {

constexpr std::array<std::uint8_t, 256> make_j1850_table() {
  std::array<std::uint8_t, 256> t{};
  for (unsigned i = 0; i < 256; ++i) {
    unsigned c = i;
    for (int b = 0; b < 8; ++b) c = (c & 0x80u) != 0 ? ((c << 1) ^ 0x1Du) : (c << 1);
    t[i] = static_cast<std::uint8_t>(c & 0xFFu);
  }
  return t;
}
constexpr std::array<std::uint8_t, 256> kJ1850 = make_j1850_table();

}  // namespace

std::uint8_t crc8_sae_j1850(core::ByteSpan bytes) noexcept {
  std::uint8_t crc = 0xFF;
  for (const std::uint8_t b : bytes) crc = kJ1850[crc ^ b];
  return static_cast<std::uint8_t>(crc ^ 0xFFu);
}

std::uint32_t crc32_ieee(core::ByteSpan bytes) noexcept {
  boost::crc_32_type crc;
  crc.process_bytes(bytes.data(), bytes.size());
  return crc.checksum();
}

}  // namespace cndt::output
