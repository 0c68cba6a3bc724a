// Laser tables and packet timing of the sensors the decoder knows. Angles are the nominal factory
// values from the sensors' user manuals; timings are the manuals' firing schedules.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string_view>

namespace cndt::vlp16 {

enum class Model : std::uint8_t { kVlp16, kVlp16HiRes, kHdl32e, kVlp32c };

/// Product-id byte (payload offset 1205) values, VLP-16 manual section 9.
enum ProductId : std::uint8_t {
  kProductHdl32e = 0x21,
  kProductVlp16 = 0x22,
  kProductVlp32ab = 0x23,
  kProductVlp16HiRes = 0x24,
  kProductVlp32c = 0x28,
  kProductVelarray = 0x31,
  kProductVls128 = 0xA1,
};

/// Return-mode byte (payload offset 1204).
enum class ReturnMode : std::uint8_t { kStrongest = 0x37, kLast = 0x38, kDual = 0x39 };

struct LaserTable {
  Model model;
  std::string_view name;
  int lasers;                 ///< lasers in one firing sequence (16 or 32)
  int sequences_per_block;    ///< firing sequences carried by one data block (2 or 1)
  double range_unit_m;        ///< metres per distance count
  double firing_spacing_us;   ///< time between consecutive firings inside a sequence
  int lasers_per_firing;      ///< lasers that fire together (1, or 2 on the VLP-32C)
  double sequence_period_us;  ///< one firing sequence including recharge
  std::array<double, 32> elevation_deg;
  std::array<double, 32> azimuth_offset_deg;  ///< added to the firing azimuth (VLP-32C only)
  std::array<double, 32> vertical_offset_m;   ///< laser origin height, added to z
  std::array<std::uint8_t, 32> ring;          ///< laser id -> ring, 0 = lowest elevation

  /// Duration of one data packet in single-return mode (12 blocks).
  [[nodiscard]] double packet_period_us(ReturnMode mode) const noexcept {
    const double single = 12.0 * sequences_per_block * sequence_period_us;
    return mode == ReturnMode::kDual ? single / 2.0 : single;
  }
  /// Time of laser `laser` after the start of its firing sequence.
  [[nodiscard]] double laser_offset_us(int laser) const noexcept {
    return firing_spacing_us * (laser / lasers_per_firing);
  }
};

const LaserTable& laser_table(Model model) noexcept;

std::string_view model_name(Model model) noexcept;
/// Parses "vlp16", "vlp16-hires", "hdl32e", "vlp32c" (case-insensitive); nullopt otherwise.
std::optional<Model> parse_model(std::string_view text) noexcept;
/// The model a product-id byte names, or nullopt for unknown or unsupported ids.
std::optional<Model> model_from_product_id(std::uint8_t id) noexcept;
/// A readable name for any product-id byte, including ones cndt cannot decode.
std::string_view product_id_name(std::uint8_t id) noexcept;
std::string_view return_mode_name(ReturnMode mode) noexcept;

}  // namespace cndt::vlp16
