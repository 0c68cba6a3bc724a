#include "cndt/pcap/frame.hpp"

#include <arpa/inet.h>
#include <fmt/format.h>

namespace cndt::pcap {
namespace {

using core::load_be16;

// libpcap DLT values (pcap/dlt.h); spelled out so this file does not need pcap.h.
constexpr int kDltNull = 0;
constexpr int kDltEthernet = 1;
constexpr int kDltRaw = 12;
constexpr int kDltRawOpenBsd = 14;
constexpr int kDltLoop = 108;
constexpr int kDltLinuxSll = 113;
constexpr int kDltIpv4 = 228;
constexpr int kDltIpv6 = 229;
constexpr int kDltLinuxSll2 = 276;

constexpr std::uint16_t kEtherIpv4 = 0x0800;
constexpr std::uint16_t kEtherIpv6 = 0x86DD;
constexpr std::uint8_t kProtoUdp = 17;

FrameResult parse_udp(core::ByteSpan ip_payload, std::size_t declared, UdpDatagram& out) {
  if (ip_payload.size() < 8) return FrameResult::kMalformed;
  out.src_port = load_be16(ip_payload, 0);
  out.dst_port = load_be16(ip_payload, 2);
  const std::size_t udp_len = load_be16(ip_payload, 4);
  if (udp_len < 8 || udp_len > declared) return FrameResult::kMalformed;
  out.payload_size = udp_len - 8;
  const std::size_t have = ip_payload.size() - 8;
  out.payload = ip_payload.subspan(8, std::min(have, out.payload_size));
  return FrameResult::kUdp;
}

FrameResult parse_ipv4(core::ByteSpan b, UdpDatagram& out) {
  if (b.size() < 20 || (b[0] >> 4) != 4) return FrameResult::kMalformed;
  const std::size_t ihl = static_cast<std::size_t>(b[0] & 0x0F) * 4;
  const std::size_t total = load_be16(b, 2);
  if (ihl < 20 || b.size() < ihl || total < ihl) return FrameResult::kMalformed;
  const std::uint16_t frag = load_be16(b, 6);
  if (b[9] != kProtoUdp) return FrameResult::kNotUdp;
  if ((frag & 0x3FFF) != 0) return FrameResult::kFragment;  // MF flag or a fragment offset
  out.src.version = out.dst.version = 4;
  out.src.bytes = {};
  out.dst.bytes = {};
  for (std::size_t i = 0; i < 4; ++i) {
    out.src.bytes[i] = b[12 + i];
    out.dst.bytes[i] = b[16 + i];
  }
  // Captured bytes past the IP total length are link padding, not payload.
  const std::size_t end = std::min(b.size(), total);
  return parse_udp(b.subspan(ihl, end - ihl), total - ihl, out);
}

FrameResult parse_ipv6(core::ByteSpan b, UdpDatagram& out) {
  if (b.size() < 40 || (b[0] >> 4) != 6) return FrameResult::kMalformed;
  const std::size_t payload_len = load_be16(b, 4);
  std::uint8_t next = b[6];
  out.src.version = out.dst.version = 6;
  for (std::size_t i = 0; i < 16; ++i) {
    out.src.bytes[i] = b[8 + i];
    out.dst.bytes[i] = b[24 + i];
  }
  std::size_t off = 40;
  const std::size_t end = std::min(b.size(), 40 + payload_len);
  // Skip hop-by-hop (0), routing (43) and destination-options (60) extension headers.
  for (int hops = 0; hops < 8 && (next == 0 || next == 43 || next == 60); ++hops) {
    if (off + 2 > end) return FrameResult::kMalformed;
    const std::uint8_t following = b[off];
    off += (static_cast<std::size_t>(b[off + 1]) + 1) * 8;
    next = following;
  }
  if (next == 44) return FrameResult::kFragment;
  if (next != kProtoUdp) return FrameResult::kNotUdp;
  if (off > end) return FrameResult::kMalformed;
  return parse_udp(b.subspan(off, end - off), 40 + payload_len - off, out);
}

FrameResult by_ethertype(std::uint16_t type, core::ByteSpan rest, UdpDatagram& out) {
  if (type == kEtherIpv4) return parse_ipv4(rest, out);
  if (type == kEtherIpv6) return parse_ipv6(rest, out);
  return FrameResult::kNotIp;
}

FrameResult by_version(core::ByteSpan b, UdpDatagram& out) {
  if (b.empty()) return FrameResult::kMalformed;
  if ((b[0] >> 4) == 4) return parse_ipv4(b, out);
  if ((b[0] >> 4) == 6) return parse_ipv6(b, out);
  return FrameResult::kNotIp;
}

// BSD address family values for IPv6 differ between systems (24, 28, 30).
bool is_af_inet6(std::uint32_t af) { return af == 24 || af == 28 || af == 30; }

}  // namespace

std::string_view frame_result_name(FrameResult r) noexcept {
  switch (r) {
    case FrameResult::kUdp:
      return "udp";
    case FrameResult::kNotIp:
      return "not_ip";
    case FrameResult::kNotUdp:
      return "not_udp";
    case FrameResult::kFragment:
      return "ip_fragment";
    case FrameResult::kMalformed:
      return "malformed_frame";
    case FrameResult::kUnsupportedLink:
      return "unsupported_link";
  }
  return "unknown";
}

bool link_type_supported(int dlt) noexcept {
  switch (dlt) {
    case kDltNull:
    case kDltEthernet:
    case kDltRaw:
    case kDltRawOpenBsd:
    case kDltLoop:
    case kDltLinuxSll:
    case kDltIpv4:
    case kDltIpv6:
    case kDltLinuxSll2:
      return true;
    default:
      return false;
  }
}

std::string link_type_name(int dlt) {
  switch (dlt) {
    case kDltNull:
      return "BSD loopback (NULL)";
    case kDltEthernet:
      return "Ethernet";
    case kDltRaw:
    case kDltRawOpenBsd:
      return "raw IP";
    case kDltLoop:
      return "OpenBSD loopback";
    case kDltLinuxSll:
      return "Linux cooked (SLL)";
    case kDltIpv4:
      return "raw IPv4";
    case kDltIpv6:
      return "raw IPv6";
    case kDltLinuxSll2:
      return "Linux cooked v2 (SLL2)";
    default:
      return fmt::format("link type {}", dlt);
  }
}

FrameResult parse_frame(int dlt, core::ByteSpan f, UdpDatagram& out) noexcept {
  switch (dlt) {
    case kDltEthernet: {
      std::size_t off = 12;
      if (f.size() < off + 2) return FrameResult::kMalformed;
      std::uint16_t type = load_be16(f, off);
      // 802.1Q / 802.1ad / QinQ tags: 4 bytes each, possibly stacked.
      for (int tags = 0; tags < 4 && (type == 0x8100 || type == 0x88A8 || type == 0x9100); ++tags) {
        off += 4;
        if (f.size() < off + 2) return FrameResult::kMalformed;
        type = load_be16(f, off);
      }
      return by_ethertype(type, f.subspan(off + 2), out);
    }
    case kDltLinuxSll:
      if (f.size() < 16) return FrameResult::kMalformed;
      return by_ethertype(load_be16(f, 14), f.subspan(16), out);
    case kDltLinuxSll2:
      if (f.size() < 20) return FrameResult::kMalformed;
      return by_ethertype(load_be16(f, 0), f.subspan(20), out);
    case kDltRaw:
    case kDltRawOpenBsd:
      return by_version(f, out);
    case kDltIpv4:
      return parse_ipv4(f, out);
    case kDltIpv6:
      return parse_ipv6(f, out);
    case kDltNull:
    case kDltLoop: {
      if (f.size() < 4) return FrameResult::kMalformed;
      // NULL stores the family in the writer's byte order, LOOP in network order: accept both.
      const std::uint32_t le = core::load_le32(f, 0);
      const std::uint32_t be = core::load_be32(f, 0);
      if (le == 2 || be == 2) return parse_ipv4(f.subspan(4), out);
      if (is_af_inet6(le) || is_af_inet6(be)) return parse_ipv6(f.subspan(4), out);
      return FrameResult::kNotIp;
    }
    default:
      return FrameResult::kUnsupportedLink;
  }
}

}  // namespace cndt::pcap
