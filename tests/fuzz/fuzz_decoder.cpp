// Any byte string offered as a data or position payload: the driver validates, counts and
// decodes without crashing, and every scan it hands out keeps its invariants.
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <vector>

#include "cndt/vlp16/driver.hpp"

namespace {

void check(const cndt::core::Scan& s) {
  if (s.points.size() > s.points.capacity()) std::abort();
  std::uint32_t prev = 0;
  for (const auto& p : s.points) {
    if (p.time_ns < prev) std::abort();  // point times never decrease
    prev = p.time_ns;
    if (!(p.x == p.x) || !(p.y == p.y) || !(p.z == p.z)) std::abort();  // no NaN
  }
  if (s.end < s.stamp) std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  // The input is a sequence of packets: 1 byte of kind/model control, 2 bytes of length, payload.
  if (size < 1) return 0;
  cndt::vlp16::DriverOptions opt;
  const std::uint8_t control = data[0];
  if ((control & 3) == 1) opt.model = std::nullopt;
  if ((control & 3) == 2) opt.model = cndt::vlp16::Model::kHdl32e;
  if ((control & 3) == 3) opt.model = cndt::vlp16::Model::kVlp32c;
  opt.assembler.max_points = 2000;
  cndt::vlp16::Driver driver(opt);
  auto sink = [](cndt::core::Scan& s) { check(s); };
  std::size_t off = 1;
  std::vector<std::uint8_t> payload;
  std::int64_t t = 1'700'000'000'000'000'000;
  while (off + 3 <= size) {
    const bool position = (data[off] & 1) != 0;
    std::size_t len =
        static_cast<std::size_t>(data[off + 1]) | (static_cast<std::size_t>(data[off + 2]) << 8);
    off += 3;
    // Lengths are mostly steered to the real sizes so that validation is passed often.
    if ((len & 0x8000) == 0) len = position ? 512 : 1206;
    len &= 0x7FF;
    len = std::min(len, size - off);
    payload.assign(data + off, data + off + len);
    off += len;
    t += 1'327'104;
    if (position) {
      driver.on_position(payload);
    } else {
      driver.on_data(payload, std::chrono::nanoseconds(t), sink);
    }
  }
  driver.finish(sink);
  const auto& s = driver.stats();
  if (s.decoded_packets + s.rejected_total() != s.data_packets) {
    std::abort();  // every data packet is decoded or refused with a reason
  }
  return 0;
}
