// An IPv4 or IPv6 address as bytes, comparable and printable.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

namespace cndt::io {

struct IpAddress {
  std::uint8_t version = 4;              ///< 4 or 6
  std::array<std::uint8_t, 16> bytes{};  ///< IPv4 uses the first 4

  static std::optional<IpAddress> parse(std::string_view text);
  static IpAddress v4(std::uint8_t a, std::uint8_t b, std::uint8_t c, std::uint8_t d);
  [[nodiscard]] std::string to_string() const;
  bool operator==(const IpAddress&) const = default;
};

}  // namespace cndt::io
