// Hand-built link-layer frames carrying a UDP payload, for parser and reader tests.
#pragma once

#include <cstdint>
#include <vector>

#include "cndt/core/bytes.hpp"

namespace cndt::test {

inline std::vector<std::uint8_t> ipv4_udp(const std::vector<std::uint8_t>& payload,
                                          std::uint16_t dport, std::uint8_t src_last = 201,
                                          std::uint16_t frag = 0) {
  std::vector<std::uint8_t> f(28 + payload.size(), 0);
  f[0] = 0x45;
  core::store_be16(f, 2, static_cast<std::uint16_t>(f.size()));
  core::store_be16(f, 6, frag);
  f[8] = 64;
  f[9] = 17;
  f[12] = 192;
  f[13] = 168;
  f[14] = 1;
  f[15] = src_last;
  f[16] = 255;
  f[17] = 255;
  f[18] = 255;
  f[19] = 255;
  core::store_be16(f, 20, 2368);
  core::store_be16(f, 22, dport);
  core::store_be16(f, 24, static_cast<std::uint16_t>(8 + payload.size()));
  std::copy(payload.begin(), payload.end(), f.begin() + 28);
  return f;
}

inline std::vector<std::uint8_t> ipv6_udp(const std::vector<std::uint8_t>& payload,
                                          std::uint16_t dport, bool with_hop_by_hop) {
  const std::size_t ext = with_hop_by_hop ? 8 : 0;
  std::vector<std::uint8_t> f(40 + ext + 8 + payload.size(), 0);
  f[0] = 0x60;
  core::store_be16(f, 4, static_cast<std::uint16_t>(ext + 8 + payload.size()));
  f[6] = with_hop_by_hop ? 0 : 17;
  f[7] = 64;
  f[8] = 0xFE;
  f[9] = 0x80;
  f[23] = 0x01;
  f[24] = 0xFF;
  f[25] = 0x02;
  f[39] = 0x01;
  std::size_t off = 40;
  if (with_hop_by_hop) {
    f[40] = 17;  // next header
    f[41] = 0;   // length in 8-byte units beyond the first 8
    off += 8;
  }
  core::store_be16(f, off, 2368);
  core::store_be16(f, off + 2, dport);
  core::store_be16(f, off + 4, static_cast<std::uint16_t>(8 + payload.size()));
  std::copy(payload.begin(), payload.end(), f.begin() + static_cast<std::ptrdiff_t>(off + 8));
  return f;
}

inline std::vector<std::uint8_t> prepend(std::vector<std::uint8_t> head,
                                         const std::vector<std::uint8_t>& tail) {
  head.insert(head.end(), tail.begin(), tail.end());
  return head;
}

inline std::vector<std::uint8_t> ethernet(const std::vector<std::uint8_t>& ip,
                                          std::uint16_t ethertype = 0x0800, int vlan_tags = 0) {
  std::vector<std::uint8_t> h(12, 0xAA);
  for (int i = 0; i < vlan_tags; ++i) {
    h.push_back(0x81);
    h.push_back(0x00);
    h.push_back(0x00);
    h.push_back(0x05);
  }
  h.push_back(static_cast<std::uint8_t>(ethertype >> 8));
  h.push_back(static_cast<std::uint8_t>(ethertype & 0xFF));
  return prepend(h, ip);
}

}  // namespace cndt::test
