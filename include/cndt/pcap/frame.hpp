// Link layer -> IP -> UDP, for every link type a LiDAR capture is seen in. Lengths are checked
// before each header is read; nothing is cast over the frame bytes.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include "cndt/core/bytes.hpp"
#include "cndt/io/ip_address.hpp"

namespace cndt::pcap {

using io::IpAddress;

struct UdpDatagram {
  IpAddress src, dst;
  std::uint16_t src_port = 0, dst_port = 0;
  core::ByteSpan payload;        ///< the captured part of the UDP payload
  std::size_t payload_size = 0;  ///< the size the UDP header declares
  [[nodiscard]] bool truncated() const noexcept { return payload.size() < payload_size; }
};

enum class FrameResult : std::uint8_t {
  kUdp,
  kNotIp,            ///< ARP, LLDP, ... : not an IP packet
  kNotUdp,           ///< IP, but TCP, ICMP, ...
  kFragment,         ///< a fragment of a larger IP datagram (not reassembled)
  kMalformed,        ///< a header is cut short or inconsistent
  kUnsupportedLink,  ///< link type cndt does not parse
};

std::string_view frame_result_name(FrameResult r) noexcept;

/// Link types (libpcap DLT_ values) parse_frame understands.
bool link_type_supported(int dlt) noexcept;
std::string link_type_name(int dlt);

/// Finds the UDP datagram in a captured frame of link type `dlt`.
FrameResult parse_frame(int dlt, core::ByteSpan frame, UdpDatagram& out) noexcept;

}  // namespace cndt::pcap
