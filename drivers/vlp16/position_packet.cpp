#include "cndt/vlp16/position_packet.hpp"

#include <algorithm>
#include <cstdio>

namespace cndt::vlp16 {
namespace {
constexpr std::size_t kTimestampOffset = 0xC6;
constexpr std::size_t kPpsOffset = 0xCA;
constexpr std::size_t kNmeaOffset = 0xCE;
constexpr std::size_t kNmeaMax = 128;

int hex_value(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  return -1;
}

}  // namespace

std::string_view nmea_field(std::string_view sentence, int index) noexcept {
  for (int i = 0; i < index; ++i) {
    const auto comma = sentence.find(',');
    if (comma == std::string_view::npos) return {};
    sentence.remove_prefix(comma + 1);
  }
  return sentence.substr(0, std::min(sentence.find(','), sentence.find('*')));
}

std::string_view pps_state_name(PpsState s) noexcept {
  switch (s) {
    case PpsState::kAbsent:
      return "absent";
    case PpsState::kSynchronizing:
      return "synchronizing";
    case PpsState::kLocked:
      return "locked";
    case PpsState::kError:
      return "error";
  }
  return "invalid";
}

PositionError parse_position_packet(core::ByteSpan payload, PositionPacket& out) noexcept {
  if (payload.size() != 512) return PositionError::kWrongSize;
  out = PositionPacket{};
  out.toh_us = core::load_le32(payload, kTimestampOffset);
  const std::uint8_t pps = payload[kPpsOffset];
  if (pps > 3) return PositionError::kBadPps;
  out.pps = static_cast<PpsState>(pps);
  if (payload[kNmeaOffset] != '$') return PositionError::kNone;
  std::size_t n = 0;
  while (n < kNmeaMax && n + 1 < out.nmea.size()) {
    const auto c = static_cast<char>(payload[kNmeaOffset + n]);
    if (c == '\r' || c == '\n' || c == '\0' || c < 0x20 || c > 0x7E) break;
    out.nmea[n++] = c;
  }
  out.nmea[n] = '\0';
  out.has_nmea = true;
  const std::string_view s = out.sentence();
  const auto star = s.find('*');
  // "*hh": two hex digits after the star, XOR of every character between '$' and '*'.
  if (star != std::string_view::npos && star + 2 < s.size()) {
    unsigned sum = 0;
    for (std::size_t i = 1; i < star; ++i) sum ^= static_cast<unsigned char>(s[i]);
    const int hi = hex_value(s[star + 1]);
    const int lo = hex_value(s[star + 2]);
    out.nmea_checksum_ok = hi >= 0 && lo >= 0 && static_cast<unsigned>(hi * 16 + lo) == sum;
  }
  const std::string_view id = nmea_field(s, 0);
  const bool rmc = id.size() >= 6 && id.substr(3) == "RMC";
  const bool gga = id.size() >= 6 && id.substr(3) == "GGA";
  const std::string_view time = nmea_field(s, 1);
  if ((rmc || gga) && time.size() >= 6 &&
      std::all_of(time.begin(), time.begin() + 6, [](char c) { return c >= '0' && c <= '9'; })) {
    auto two = [&](std::size_t i) { return (time[i] - '0') * 10 + (time[i + 1] - '0'); };
    out.utc_seconds_of_day = two(0) * 3600 + two(2) * 60 + two(4);
  }
  if (rmc) out.fix_valid = nmea_field(s, 2) == "A";
  if (gga) {
    const std::string_view q = nmea_field(s, 6);
    out.fix_valid = !q.empty() && q != "0";
  }
  return PositionError::kNone;
}

}  // namespace cndt::vlp16
