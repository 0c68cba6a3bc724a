#include "cndt/pcap/pcap_source.hpp"

#include <fmt/format.h>
#include <pcap/pcap.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <thread>

namespace cndt::pcap {
namespace {

pcap_t* as_pcap(void* h) { return static_cast<pcap_t*>(h); }

core::Error open_error(const std::string& path, const std::string& why, int code) {
  return core::Error{code, fmt::format("cannot read capture '{}': {}", path, why)};
}

// Reads the first four bytes to tell pcap and pcapng apart and to refuse other files clearly.
std::optional<bool> sniff_pcapng(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::array<unsigned char, 4> m{};
  if (!in.read(reinterpret_cast<char*>(m.data()), 4)) return std::nullopt;
  const std::uint32_t le = core::load_le32(core::ByteSpan(m), 0);
  if (le == 0x0A0D0D0A) return true;
  if (le == 0xA1B2C3D4 || le == 0xD4C3B2A1 || le == 0xA1B23C4D || le == 0x4D3CB2A1) return false;
  return std::nullopt;
}

}  // namespace

core::Result<std::unique_ptr<PcapSource>> PcapSource::open(const std::string& path,
                                                           const PcapOptions& options) {
  namespace fs = std::filesystem;
  std::error_code ec;
  const auto status = fs::status(path, ec);
  if (ec || !fs::exists(status)) {
    return open_error(path, "no such file", core::kExitNoInput);
  }
  if (fs::is_directory(status)) {
    return open_error(path, "it is a directory, not a capture file", core::kExitNoInput);
  }
  std::FILE* probe = std::fopen(path.c_str(), "rb");
  if (probe == nullptr) {
    return open_error(path, std::strerror(errno), core::kExitNoInput);
  }
  std::fclose(probe);
  const auto size = fs::file_size(path, ec);
  if (!ec && size == 0) {
    return open_error(path, "the file is empty (0 bytes)", core::kExitDataError);
  }
  const std::optional<bool> ng = sniff_pcapng(path);
  if (!ng) {
    return open_error(path, "not a pcap or pcapng file (unknown magic number)",
                      core::kExitDataError);
  }
  char errbuf[PCAP_ERRBUF_SIZE] = {};
  pcap_t* p =
      pcap_open_offline_with_tstamp_precision(path.c_str(), PCAP_TSTAMP_PRECISION_NANO, errbuf);
  if (p == nullptr) {
    return open_error(path, errbuf, core::kExitDataError);
  }
  const int dlt = pcap_datalink(p);
  if (!link_type_supported(dlt)) {
    pcap_close(p);
    return open_error(path,
                      fmt::format("link type {} is not supported (Ethernet, Linux SLL/SLL2, raw "
                                  "IP and BSD loopback are)",
                                  link_type_name(dlt)),
                      core::kExitDataError);
  }
  return std::unique_ptr<PcapSource>(new PcapSource(path, options, p, dlt, *ng));
}

PcapSource::PcapSource(std::string path, const PcapOptions& options, void* handle, int link_type,
                       bool pcapng)
    : path_(std::move(path)),
      options_(options),
      handle_(handle),
      link_type_(link_type),
      pcapng_(pcapng) {}

PcapSource::~PcapSource() { pcap_close(as_pcap(handle_)); }

io::NextResult PcapSource::next(io::SourcePacket& packet, std::chrono::milliseconds /*timeout*/) {
  while (!ended_) {
    pcap_pkthdr* hdr = nullptr;
    const u_char* data = nullptr;
    std::FILE* file = pcap_file(as_pcap(handle_));
    const long offset = file != nullptr ? std::ftell(file) : -1;
    const int rc = pcap_next_ex(as_pcap(handle_), &hdr, &data);
    if (rc == PCAP_ERROR_BREAK) {
      ended_ = true;
      break;
    }
    if (rc != 1) {
      // libpcap reports a file that ends inside a record as an error; it is the normal end of a
      // capture cut short, so the replay ends here with everything before it delivered.
      inspect_truncated_record(offset, pcap_geterr(as_pcap(handle_)));
      ended_ = true;
      break;
    }
    ++stats_.records;
    const std::chrono::nanoseconds t(static_cast<std::int64_t>(hdr->ts.tv_sec) * 1'000'000'000 +
                                     static_cast<std::int64_t>(hdr->ts.tv_usec));
    if (!stats_.first_time) stats_.first_time = t;
    stats_.last_time = t;
    UdpDatagram d;
    const FrameResult r = parse_frame(link_type_, core::ByteSpan(data, hdr->caplen), d);
    if (r != FrameResult::kUdp) {
      ++stats_.skipped[r];
      continue;
    }
    ++stats_.udp;
    ++stats_.udp_by_dest_port[d.dst_port];
    const bool is_data = d.dst_port == options_.data_port;
    const bool is_position = d.dst_port == options_.position_port;
    if (!is_data && !is_position) continue;
    if (options_.sensor_ip && d.src != *options_.sensor_ip) {
      ++stats_.wrong_source;
      continue;
    }
    if (d.truncated()) ++stats_.cut_payloads;  // delivered; the decoder refuses its size
    if (is_data) {
      ++stats_.data;
    } else {
      ++stats_.position;
    }
    packet.kind = is_data ? io::PacketKind::kData : io::PacketKind::kPosition;
    packet.time = t;
    packet.payload = d.payload;
    packet.source = d.src;
    packet.source_port = d.src_port;
    packet.dest_port = d.dst_port;
    packet.index = stats_.records;
    if (options_.speed > 0.0) pace(t);
    return io::NextResult::kPacket;
  }
  return io::NextResult::kEnd;
}

void PcapSource::pace(std::chrono::nanoseconds capture_time) {
  const auto now = std::chrono::steady_clock::now();
  if (!pace_capture_start_) {
    pace_capture_start_ = capture_time;
    pace_wall_start_ = now;
    return;
  }
  const auto offset = std::chrono::duration_cast<std::chrono::nanoseconds>(
      (capture_time - *pace_capture_start_) / options_.speed);
  std::this_thread::sleep_until(pace_wall_start_ + offset);
}

void PcapSource::inspect_truncated_record(long record_offset, const std::string& message) {
  TruncatedRecord t;
  t.index = stats_.records + 1;
  t.message = message;
  // Classic pcap: read the cut record ourselves to say what it was. pcapng blocks are not
  // inspected; libpcap's message still says what happened.
  std::FILE* file = pcap_file(as_pcap(handle_));
  if (!pcapng_ && file != nullptr && record_offset >= 0 &&
      std::fseek(file, record_offset, SEEK_SET) == 0) {
    std::vector<std::uint8_t> rest(65536 + 16);
    const std::size_t n = std::fread(rest.data(), 1, rest.size(), file);
    if (n >= 16) {
      const bool swapped = pcap_is_swapped(as_pcap(handle_)) != 0;
      const core::ByteSpan h(rest.data(), 16);
      t.declared = swapped ? core::load_be32(h, 8) : core::load_le32(h, 8);
      t.present = n - 16;
      UdpDatagram d;
      if (parse_frame(link_type_, core::ByteSpan(rest.data() + 16, n - 16), d) ==
          FrameResult::kUdp) {
        t.dest_port = d.dst_port;
      }
    } else {
      t.present = n;
    }
  }
  stats_.truncated = t;
}

}  // namespace cndt::pcap
