// Link-layer parsing of arbitrary frames for every supported link type.
#include <cstdint>
#include <cstdlib>

#include "cndt/pcap/frame.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  static constexpr int kLinks[] = {0, 1, 12, 14, 108, 113, 228, 229, 276};
  const int dlt = kLinks[data[0] % 9];
  cndt::pcap::UdpDatagram d;
  const cndt::core::ByteSpan frame(data + 1, size - 1);
  if (cndt::pcap::parse_frame(dlt, frame, d) == cndt::pcap::FrameResult::kUdp) {
    // The payload must lie inside the frame.
    if (d.payload.data() < frame.data() ||
        d.payload.data() + d.payload.size() > frame.data() + frame.size()) {
      std::abort();
    }
  }
  return 0;
}
