#include "cndt/vlp16/driver.hpp"

#include <spdlog/spdlog.h>

#include <cstdlib>

namespace cndt::vlp16 {

std::string DriverStats::rejects_text() const {
  std::string out;
  for (std::size_t i = 0; i < rejected.size(); ++i) {
    if (rejected[i] == 0) continue;
    out += fmt::format("{}{} {}", out.empty() ? "" : ", ", rejected[i],
                       packet_error_name(static_cast<PacketError>(i)));
  }
  return out.empty() ? "none" : out;
}

Driver::Driver(const DriverOptions& options)
    : options_(options),
      assembler_(options.assembler, laser_table(options.model.value_or(Model::kVlp16))
                                        .packet_period_us(ReturnMode::kStrongest)) {
  if (options_.model) decoder_.emplace(*options_.model, options_.decoder);
}

void Driver::note_header(const PacketHeader& header) {
  if (header.legacy_factory_bytes) ++stats_.legacy_factory_packets;
  if (!stats_.return_mode) stats_.return_mode = header.mode;
  if (!stats_.product_id) {
    stats_.product_id = header.product_id;
    if (options_.model && !header.legacy_factory_bytes &&
        model_from_product_id(header.product_id) != options_.model) {
      stats_.model_mismatch = true;
      spdlog::warn(
          "packets report product id 0x{:02X} ({}) but the configured model is {}; decoding as {} "
          "(early VLP-16 firmware reports 0x21; set the model to auto to follow the packets)",
          header.product_id, product_id_name(header.product_id), model_name(*options_.model),
          model_name(*options_.model));
    }
  }
}

bool Driver::resolve_model(const PacketHeader& header) {
  if (header.legacy_factory_bytes) {
    decoder_.emplace(Model::kVlp16, options_.decoder);
    return true;
  }
  const Model named = model_from_product_id(header.product_id).value_or(Model::kVlp16);
  if (header.product_id != kProductHdl32e) {
    decoder_.emplace(named, options_.decoder);
    return true;
  }
  if (!holding_) return false;
  // 0x21: HDL-32E sends a packet every 552.96 us, early VLP-16 firmware every 1327.104 us
  // (halved in dual mode for both). The sensor clock step between two packets tells them apart.
  const std::int64_t step =
      (static_cast<std::int64_t>(header.toh_us) - held_header_.toh_us + 3'600'000'000LL) %
      3'600'000'000LL;
  const double dual = header.mode == ReturnMode::kDual ? 0.5 : 1.0;
  const double to_hdl = std::abs(static_cast<double>(step) - 552.96 * dual);
  const double to_vlp = std::abs(static_cast<double>(step) - 1327.104 * dual);
  const Model chosen = to_hdl <= to_vlp ? Model::kHdl32e : Model::kVlp16;
  decoder_.emplace(chosen, options_.decoder);
  spdlog::info("product id 0x21 with {:.0f} us between packets: decoding as {}",
               static_cast<double>(step), model_name(chosen));
  return true;
}

PositionError Driver::on_position(core::ByteSpan payload) noexcept {
  PositionPacket p;
  const PositionError err = parse_position_packet(payload, p);
  if (err != PositionError::kNone) {
    ++stats_.position_rejected;
    return err;
  }
  ++stats_.position_packets;
  if (p.has_nmea) ++stats_.position_with_nmea;
  stats_.last_position = p;
  return err;
}

}  // namespace cndt::vlp16
