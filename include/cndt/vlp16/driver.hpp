// The sensor driver: data and position payloads in, time-stamped scans out. Validates every
// packet, resolves the sensor model, makes timestamps absolute and assembles revolutions.
#pragma once

#include <array>
#include <chrono>
#include <cstdint>
#include <optional>
#include <string>

#include "cndt/core/bytes.hpp"
#include "cndt/vlp16/decoder.hpp"
#include "cndt/vlp16/hour_clock.hpp"
#include "cndt/vlp16/position_packet.hpp"
#include "cndt/vlp16/scan_assembler.hpp"

namespace cndt::vlp16 {

struct DriverOptions {
  /// The sensor model; nullopt = auto (from the product byte, with the packet period deciding
  /// between HDL-32E and early VLP-16 firmware, which both report 0x21).
  std::optional<Model> model = Model::kVlp16;
  DecoderOptions decoder;
  AssemblerOptions assembler;
};

struct DriverStats {
  std::uint64_t data_packets = 0;  ///< data payloads offered
  std::uint64_t decoded_packets = 0;
  std::array<std::uint64_t, static_cast<std::size_t>(PacketError::kCount)> rejected{};
  std::uint64_t position_packets = 0;
  std::uint64_t position_rejected = 0;
  std::uint64_t legacy_factory_packets = 0;
  std::optional<std::uint8_t> product_id;  ///< first product byte seen
  std::optional<ReturnMode> return_mode;   ///< first return mode seen
  bool model_mismatch = false;             ///< product byte disagreed with the configured model
  std::optional<PositionPacket> last_position;
  std::uint64_t position_with_nmea = 0;
  std::uint64_t hour_rollovers = 0;
  std::optional<std::chrono::nanoseconds> first_packet_time, last_packet_time;
  /// Rotor travel between consecutive packets, to measure the spin rate: 0.01 deg and ns.
  std::uint64_t azimuth_travel = 0;
  std::uint64_t azimuth_travel_ns = 0;

  /// Rotations per minute measured from the packets, or 0 when too few were decoded.
  [[nodiscard]] double rpm() const noexcept {
    if (azimuth_travel_ns == 0) return 0.0;
    return static_cast<double>(azimuth_travel) / 36000.0 /
           (static_cast<double>(azimuth_travel_ns) * 1e-9) * 60.0;
  }

  [[nodiscard]] std::uint64_t rejected_total() const noexcept {
    std::uint64_t n = 0;
    for (auto v : rejected) n += v;
    return n;
  }
  /// The rejects by reason, "12 bad_flag, 3 unsupported_model"; "none" without any.
  [[nodiscard]] std::string rejects_text() const;
};

class Driver {
 public:
  explicit Driver(const DriverOptions& options);

  /// Feeds one payload received on the data port. `reference` is the receive or capture time,
  /// used only to find the hour. Completed scans go to `sink(core::Scan&)`.
  template <class Sink>
  PacketError on_data(core::ByteSpan payload, std::chrono::nanoseconds reference, Sink&& sink);
  /// Feeds one payload received on the position port.
  PositionError on_position(core::ByteSpan payload) noexcept;
  /// Ends the stream: hands out the scan in progress (and any packet held for model detection).
  template <class Sink>
  void finish(Sink&& sink);

  [[nodiscard]] const DriverStats& stats() const noexcept { return stats_; }
  [[nodiscard]] const AssemblerStats& assembler_stats() const noexcept {
    return assembler_.stats();
  }
  /// The model packets are decoded as; nullopt while auto-detection still waits for packets.
  [[nodiscard]] std::optional<Model> model() const noexcept {
    return decoder_ ? std::optional<Model>(decoder_->model()) : std::nullopt;
  }

 private:
  // Picks the model for the first valid packet. Returns false while it needs a second packet.
  bool resolve_model(const PacketHeader& header);
  void note_header(const PacketHeader& header);
  template <class Sink>
  void decode_and_add(core::ByteSpan payload, const PacketHeader& header,
                      std::chrono::nanoseconds reference, Sink&& sink);

  DriverOptions options_;
  std::optional<Decoder> decoder_;
  ScanAssembler assembler_;
  HourClock clock_;
  DecodedPacket decoded_;
  // Auto mode with an ambiguous product byte holds the first packet until the second shows the
  // packet period.
  std::array<std::uint8_t, kDataPacketSize> held_{};
  PacketHeader held_header_{};
  std::chrono::nanoseconds held_reference_{0};
  bool holding_ = false;
  std::optional<ReturnMode> period_mode_;
  int last_azimuth_ = 0;
  DriverStats stats_;
};

template <class Sink>
void Driver::decode_and_add(core::ByteSpan payload, const PacketHeader& header,
                            std::chrono::nanoseconds reference, Sink&& sink) {
  if (!period_mode_ || *period_mode_ != header.mode) {
    // Loss detection needs the packet period of the model and return mode in use.
    assembler_.set_packet_period_us(decoder_->table().packet_period_us(header.mode));
    period_mode_ = header.mode;
  }
  decoder_->decode(payload, header, decoded_);
  const std::chrono::nanoseconds t = clock_.resolve(header.toh_us, reference);
  if (stats_.last_packet_time && decoded_.firing_count > 0) {
    const auto dt = t - *stats_.last_packet_time;
    const int step = (decoded_.firings[0].azimuth - last_azimuth_ + 36000) % 36000;
    if (dt.count() > 0 && dt < options_.assembler.max_gap && step < 18000) {
      stats_.azimuth_travel += static_cast<std::uint64_t>(step);
      stats_.azimuth_travel_ns += static_cast<std::uint64_t>(dt.count());
    }
  }
  if (decoded_.firing_count > 0) last_azimuth_ = decoded_.firings[0].azimuth;
  if (!stats_.first_packet_time) stats_.first_packet_time = t;
  stats_.last_packet_time = t;
  stats_.hour_rollovers = clock_.rollovers();
  assembler_.add(decoded_, t, sink, reference);
  ++stats_.decoded_packets;
}

template <class Sink>
PacketError Driver::on_data(core::ByteSpan payload, std::chrono::nanoseconds reference,
                            Sink&& sink) {
  ++stats_.data_packets;
  PacketHeader header;
  const PacketError err = validate_data_packet(payload, header);
  if (err != PacketError::kNone) {
    ++stats_.rejected[static_cast<std::size_t>(err)];
    return err;
  }
  note_header(header);
  if (!decoder_) {
    if (!resolve_model(header)) {
      std::copy(payload.begin(), payload.end(), held_.begin());
      held_header_ = header;
      held_reference_ = reference;
      holding_ = true;
      return PacketError::kNone;
    }
    if (holding_) {
      holding_ = false;
      decode_and_add(core::ByteSpan(held_), held_header_, held_reference_, sink);
    }
  }
  decode_and_add(payload, header, reference, sink);
  return PacketError::kNone;
}

template <class Sink>
void Driver::finish(Sink&& sink) {
  if (holding_) {
    // Only one packet ever came: decode it with the product byte's own model.
    decoder_.emplace(model_from_product_id(held_header_.product_id).value_or(Model::kVlp16),
                     options_.decoder);
    holding_ = false;
    decode_and_add(core::ByteSpan(held_), held_header_, held_reference_, sink);
  }
  assembler_.flush(sink);
}

}  // namespace cndt::vlp16
