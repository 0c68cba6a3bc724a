#include "cndt/vlp16/calibration.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <numeric>
#include <string>

namespace cndt::vlp16 {
namespace {

// Ring = rank of the laser's elevation, lowest first.
std::array<std::uint8_t, 32> rings_from_elevation(const std::array<double, 32>& el, int lasers) {
  std::array<int, 32> order{};
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.begin() + lasers, [&el](int a, int b) {
    return el[static_cast<std::size_t>(a)] < el[static_cast<std::size_t>(b)];
  });
  std::array<std::uint8_t, 32> ring{};
  for (int r = 0; r < lasers; ++r) {
    ring[static_cast<std::size_t>(order[static_cast<std::size_t>(r)])] =
        static_cast<std::uint8_t>(r);
  }
  return ring;
}

LaserTable make_vlp16(Model model, std::string_view name, const std::array<double, 16>& el,
                      const std::array<double, 16>& offset_mm) {
  LaserTable t{};
  t.model = model;
  t.name = name;
  t.lasers = 16;
  t.sequences_per_block = 2;
  t.range_unit_m = 0.002;
  t.firing_spacing_us = 2.304;  // VLP-16 manual 9.5: 2.304 us between firings
  t.lasers_per_firing = 1;
  t.sequence_period_us = 55.296;  // 16 x 2.304 + 18.432 us recharge
  for (std::size_t i = 0; i < 16; ++i) {
    t.elevation_deg[i] = el[i];
    t.vertical_offset_m[i] = offset_mm[i] * 1e-3;
  }
  t.ring = rings_from_elevation(t.elevation_deg, 16);
  return t;
}

LaserTable make_hdl32e() {
  LaserTable t{};
  t.model = Model::kHdl32e;
  t.name = "HDL-32E";
  t.lasers = 32;
  t.sequences_per_block = 1;
  t.range_unit_m = 0.002;
  t.firing_spacing_us = 1.152;  // HDL-32E manual: 32 firings in 46.08 us
  t.lasers_per_firing = 1;
  t.sequence_period_us = 46.08;
  // Laser ids interleave a lower (-30.67 deg up) and an upper (-9.33 deg up) fan, 1.333 deg apart.
  for (std::size_t i = 0; i < 32; ++i) {
    const double k = static_cast<double>(i / 2);
    t.elevation_deg[i] = (i % 2 == 0) ? -30.67 + k * (4.0 / 3.0) : -9.33 + k * (4.0 / 3.0);
  }
  t.ring = rings_from_elevation(t.elevation_deg, 32);
  return t;
}

LaserTable make_vlp32c() {
  LaserTable t{};
  t.model = Model::kVlp32c;
  t.name = "VLP-32C";
  t.lasers = 32;
  t.sequences_per_block = 1;
  t.range_unit_m = 0.004;  // VLP-32C reports distance in 4 mm counts
  t.firing_spacing_us = 2.304;
  t.lasers_per_firing = 2;  // lasers fire in pairs
  t.sequence_period_us = 55.296;
  constexpr std::array<double, 32> kEl = {
      -25.0,  -1.0,   -1.667, -15.639, -11.31, 0.0,    -0.667, -8.843, -7.254, 0.333,  -0.333,
      -6.148, -5.333, 1.333,  0.667,   -4.0,   -4.667, 1.667,  1.0,    -3.667, -3.333, 3.333,
      2.333,  -2.667, -3.0,   7.0,     4.667,  -2.333, -2.0,   15.0,   10.333, -1.333};
  constexpr std::array<double, 32> kAz = {
      1.4, -4.2, 1.4, -1.4, 1.4, -1.4, 4.2, -1.4, 1.4, -4.2, 1.4, -1.4, 4.2, -1.4, 4.2, -1.4,
      1.4, -4.2, 1.4, -4.2, 4.2, -1.4, 1.4, -1.4, 1.4, -1.4, 1.4, -4.2, 4.2, -1.4, 1.4, -1.4};
  t.elevation_deg = kEl;
  t.azimuth_offset_deg = kAz;
  t.ring = rings_from_elevation(t.elevation_deg, 32);
  return t;
}

std::string lower(std::string_view s) {
  std::string out(s);
  std::transform(out.begin(), out.end(), out.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return out;
}

}  // namespace

const LaserTable& laser_table(Model model) noexcept {
  // VLP-16 manual table 9-1: elevation (deg) and vertical correction (mm) by laser id.
  static const LaserTable kVlp16 = make_vlp16(
      Model::kVlp16, "VLP-16", {-15, 1, -13, 3, -11, 5, -9, 7, -7, 9, -5, 11, -3, 13, -1, 15},
      {11.2, -0.7, 9.7, -2.2, 8.1, -3.7, 6.6, -5.1, 5.1, -6.6, 3.7, -8.1, 2.2, -9.7, 0.7, -11.2});
  static const LaserTable kHiRes = make_vlp16(
      Model::kVlp16HiRes, "VLP-16 Hi-Res",
      {-10, 0.67, -8.67, 2, -7.33, 3.33, -6, 4.67, -4.67, 6, -3.33, 7.33, -2, 8.67, -0.67, 10},
      {7.4, -0.9, 6.5, -1.8, 5.5, -2.7, 4.6, -3.7, 3.7, -4.6, 2.7, -5.5, 1.8, -6.5, 0.9, -7.4});
  static const LaserTable kHdl32e = make_hdl32e();
  static const LaserTable kVlp32c = make_vlp32c();
  switch (model) {
    case Model::kVlp16:
      return kVlp16;
    case Model::kVlp16HiRes:
      return kHiRes;
    case Model::kHdl32e:
      return kHdl32e;
    case Model::kVlp32c:
      return kVlp32c;
  }
  return kVlp16;
}

std::string_view model_name(Model model) noexcept { return laser_table(model).name; }

std::optional<Model> parse_model(std::string_view text) noexcept {
  const std::string s = lower(text);
  if (s == "vlp16" || s == "vlp-16") return Model::kVlp16;
  if (s == "vlp16-hires" || s == "vlp-16-hires") return Model::kVlp16HiRes;
  if (s == "hdl32e" || s == "hdl-32e") return Model::kHdl32e;
  if (s == "vlp32c" || s == "vlp-32c") return Model::kVlp32c;
  return std::nullopt;
}

std::optional<Model> model_from_product_id(std::uint8_t id) noexcept {
  switch (id) {
    case kProductVlp16:
      return Model::kVlp16;
    case kProductVlp16HiRes:
      return Model::kVlp16HiRes;
    case kProductHdl32e:
      return Model::kHdl32e;
    case kProductVlp32c:
      return Model::kVlp32c;
    default:
      return std::nullopt;
  }
}

std::string_view product_id_name(std::uint8_t id) noexcept {
  switch (id) {
    case kProductHdl32e:
      return "HDL-32E";
    case kProductVlp16:
      return "VLP-16";
    case kProductVlp32ab:
      return "VLP-32A/B";
    case kProductVlp16HiRes:
      return "VLP-16 Hi-Res";
    case kProductVlp32c:
      return "VLP-32C";
    case kProductVelarray:
      return "Velarray";
    case kProductVls128:
      return "VLS-128";
    default:
      return "unknown";
  }
}

std::string_view return_mode_name(ReturnMode mode) noexcept {
  switch (mode) {
    case ReturnMode::kStrongest:
      return "strongest";
    case ReturnMode::kLast:
      return "last";
    case ReturnMode::kDual:
      return "dual";
  }
  return "unknown";
}

}  // namespace cndt::vlp16
