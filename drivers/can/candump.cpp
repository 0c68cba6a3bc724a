// The candump log format (can-utils lib.h): "(<sec>.<usec>) <interface> <id>#<data>".
#include <fmt/format.h>

#include <cctype>
#include <charconv>

#include "cndt/can/can_bus.hpp"

namespace cndt::can {
namespace {

constexpr char kHex[] = "0123456789ABCDEF";

int hex_value(char c) noexcept {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

core::Error malformed(std::string_view line, std::string_view what) {
  return {core::kExitDataError, fmt::format("malformed candump line ({}): '{}'", what, line)};
}

}  // namespace

std::size_t format_candump_line(const output::CanFrame& frame, std::chrono::nanoseconds stamp,
                                std::string_view interface_name, std::span<char> out) noexcept {
  const long long ns = stamp.count() < 0 ? 0 : static_cast<long long>(stamp.count());
  // "(" 10+ digits "." 6 digits ") " iface " " 8 id "#" 16 data "\n"
  if (out.size() < 48 + interface_name.size()) return 0;
  auto r = fmt::format_to_n(out.data(), out.size(), "({:010d}.{:06d}) {} ", ns / 1'000'000'000,
                            (ns % 1'000'000'000) / 1000, interface_name);
  std::size_t n = r.size;
  if (n + 28 > out.size()) return 0;
  const int id_digits = frame.extended ? 8 : 3;
  const std::uint32_t id = frame.id & (frame.extended ? 0x1FFFFFFFu : 0x7FFu);
  for (int i = id_digits - 1; i >= 0; --i) {
    out[n++] = kHex[(id >> (4 * i)) & 0xFu];
  }
  out[n++] = '#';
  for (std::size_t i = 0; i < frame.len && i < frame.data.size(); ++i) {
    out[n++] = kHex[frame.data[i] >> 4];
    out[n++] = kHex[frame.data[i] & 0xFu];
  }
  out[n++] = '\n';
  return n;
}

core::Result<std::optional<CandumpRecord>> parse_candump_line(std::string_view line) {
  while (!line.empty() && (line.back() == '\r' || line.back() == '\n' || line.back() == ' ')) {
    line.remove_suffix(1);
  }
  std::size_t p = 0;
  while (p < line.size() && std::isspace(static_cast<unsigned char>(line[p])) != 0) ++p;
  if (p >= line.size() || line[p] != '(') return std::optional<CandumpRecord>{};
  const std::string_view full = line;
  line.remove_prefix(p + 1);
  const auto close = line.find(')');
  const auto dot = line.find('.');
  if (close == std::string_view::npos || dot == std::string_view::npos || dot > close) {
    return malformed(full, "timestamp");
  }
  long long sec = 0, frac = 0;
  const std::string_view sec_s = line.substr(0, dot),
                         frac_s = line.substr(dot + 1, close - dot - 1);
  if (sec_s.empty() || frac_s.empty() || frac_s.size() > 9 ||
      std::from_chars(sec_s.data(), sec_s.data() + sec_s.size(), sec).ptr !=
          sec_s.data() + sec_s.size() ||
      std::from_chars(frac_s.data(), frac_s.data() + frac_s.size(), frac).ptr !=
          frac_s.data() + frac_s.size() ||
      sec < 0 || frac < 0) {
    return malformed(full, "timestamp");
  }
  for (std::size_t i = frac_s.size(); i < 9; ++i) frac *= 10;
  CandumpRecord rec;
  rec.stamp = std::chrono::nanoseconds(sec * 1'000'000'000 + frac);
  line.remove_prefix(close + 1);
  // interface and frame, then an optional direction
  const auto skip_space = [&] {
    while (!line.empty() && line.front() == ' ') line.remove_prefix(1);
  };
  skip_space();
  const auto sp = line.find(' ');
  if (sp == std::string_view::npos || sp == 0) return malformed(full, "interface");
  rec.interface_name = std::string(line.substr(0, sp));
  line.remove_prefix(sp);
  skip_space();
  std::string_view frame = line.substr(0, line.find(' '));
  line.remove_prefix(frame.size());
  skip_space();
  if (!line.empty() && line != "R" && line != "T") return malformed(full, "trailing text");
  const auto hash = frame.find('#');
  if (hash == std::string_view::npos) return malformed(full, "no '#'");
  const std::string_view id_s = frame.substr(0, hash);
  std::string_view data_s = frame.substr(hash + 1);
  if (id_s.size() != 3 && id_s.size() != 8) return malformed(full, "id must be 3 or 8 hex digits");
  std::uint32_t id = 0;
  for (const char c : id_s) {
    const int v = hex_value(c);
    if (v < 0) return malformed(full, "id");
    id = (id << 4) | static_cast<std::uint32_t>(v);
  }
  rec.frame.extended = id_s.size() == 8;
  if (rec.frame.extended && (id & 0x20000000u) != 0) {
    return std::optional<CandumpRecord>{};  // an error frame: not data
  }
  rec.frame.id = id & (rec.frame.extended ? 0x1FFFFFFFu : 0x7FFu);
  if (!data_s.empty() && data_s.front() == '#')
    return malformed(full, "CAN FD frames are not supported");
  if (!data_s.empty() && (data_s.front() == 'R' || data_s.front() == 'r')) {
    return std::optional<CandumpRecord>{};  // a remote request carries no data
  }
  if (data_s.find('_') != std::string_view::npos) {
    return malformed(full, "DLC above 8 is not supported");
  }
  std::uint8_t len = 0;
  for (std::size_t i = 0; i < data_s.size();) {
    if (data_s[i] == '.') {
      ++i;
      continue;
    }
    if (i + 1 >= data_s.size()) return malformed(full, "odd number of data digits");
    const int hi = hex_value(data_s[i]), lo = hex_value(data_s[i + 1]);
    if (hi < 0 || lo < 0) return malformed(full, "data");
    if (len == 8) return malformed(full, "more than 8 data bytes");
    rec.frame.data[len++] = static_cast<std::uint8_t>((hi << 4) | lo);
    i += 2;
  }
  rec.frame.len = len;
  return std::optional<CandumpRecord>{std::move(rec)};
}

}  // namespace cndt::can
