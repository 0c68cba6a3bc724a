#include "cndt/pcap/pcap_writer.hpp"

#include <fmt/format.h>
#include <pcap/pcap.h>

#include <cerrno>
#include <cstring>

namespace cndt::pcap {
namespace {

std::uint16_t ipv4_checksum(core::ByteSpan header) {
  std::uint32_t sum = 0;
  for (std::size_t i = 0; i + 1 < header.size(); i += 2) sum += core::load_be16(header, i);
  while ((sum >> 16) != 0) sum = (sum & 0xFFFFu) + (sum >> 16);
  return static_cast<std::uint16_t>(~sum & 0xFFFFu);
}

}  // namespace

core::Result<std::unique_ptr<PcapWriter>> PcapWriter::create(const std::string& path,
                                                             bool nanosecond) {
  pcap_t* dead = pcap_open_dead_with_tstamp_precision(
      DLT_EN10MB, 65535, nanosecond ? PCAP_TSTAMP_PRECISION_NANO : PCAP_TSTAMP_PRECISION_MICRO);
  if (dead == nullptr) {
    return core::Error{core::kExitIoError, fmt::format("cannot create capture '{}'", path)};
  }
  pcap_dumper_t* dumper = pcap_dump_open(dead, path.c_str());
  if (dumper == nullptr) {
    std::string why = pcap_geterr(dead);
    pcap_close(dead);
    return core::Error{core::kExitIoError,
                       fmt::format("cannot create capture '{}': {}", path, why)};
  }
  return std::unique_ptr<PcapWriter>(new PcapWriter(path, dead, dumper, nanosecond));
}

PcapWriter::PcapWriter(std::string path, void* dead, void* dumper, bool nanosecond)
    : path_(std::move(path)), dead_(dead), dumper_(dumper), nanosecond_(nanosecond) {
  frame_.reserve(1600);
}

PcapWriter::~PcapWriter() { (void)close(); }

void PcapWriter::write_udp(std::chrono::nanoseconds time, const UdpEndpoints& ep,
                           core::ByteSpan payload) {
  const bool v6 = ep.source.version == 6;
  const std::size_t ip_len = v6 ? 40 : 20;
  const std::size_t udp_len = 8 + payload.size();
  frame_.assign(14 + ip_len + udp_len, 0);
  core::MutableByteSpan f(frame_);
  // Ethernet: broadcast destination, a locally administered source MAC, then the EtherType.
  for (std::size_t i = 0; i < 6; ++i) f[i] = 0xFF;
  const std::uint8_t mac[6] = {0x02, 0x00, 0x5E, 0x10, 0x00, 0x01};
  std::memcpy(f.data() + 6, mac, 6);
  core::store_be16(f, 12, v6 ? 0x86DD : 0x0800);
  const std::size_t ip = 14;
  if (v6) {
    f[ip] = 0x60;
    core::store_be16(f, ip + 4, static_cast<std::uint16_t>(udp_len));
    f[ip + 6] = 17;
    f[ip + 7] = 64;
    std::memcpy(f.data() + ip + 8, ep.source.bytes.data(), 16);
    std::memcpy(f.data() + ip + 24, ep.destination.bytes.data(), 16);
  } else {
    f[ip] = 0x45;
    core::store_be16(f, ip + 2, static_cast<std::uint16_t>(20 + udp_len));
    core::store_be16(f, ip + 4, ip_id_++);
    f[ip + 8] = 64;
    f[ip + 9] = 17;
    std::memcpy(f.data() + ip + 12, ep.source.bytes.data(), 4);
    std::memcpy(f.data() + ip + 16, ep.destination.bytes.data(), 4);
    core::store_be16(f, ip + 10, ipv4_checksum(core::ByteSpan(f.data() + ip, 20)));
  }
  const std::size_t udp = ip + ip_len;
  core::store_be16(f, udp, ep.source_port);
  core::store_be16(f, udp + 2, ep.dest_port);
  core::store_be16(f, udp + 4, static_cast<std::uint16_t>(udp_len));
  std::memcpy(f.data() + udp + 8, payload.data(), payload.size());

  pcap_pkthdr hdr{};
  const std::int64_t ns = time.count();
  hdr.ts.tv_sec = static_cast<time_t>(ns / 1'000'000'000);
  const std::int64_t frac = ns % 1'000'000'000;
  hdr.ts.tv_usec = static_cast<suseconds_t>(nanosecond_ ? frac : frac / 1000);
  hdr.caplen = hdr.len = static_cast<bpf_u_int32>(frame_.size());
  pcap_dump(static_cast<u_char*>(dumper_), &hdr, frame_.data());
  ++packets_;
}

std::optional<core::Error> PcapWriter::close() {
  std::optional<core::Error> err;
  if (dumper_ != nullptr) {
    auto* d = static_cast<pcap_dumper_t*>(dumper_);
    const bool failed = pcap_dump_flush(d) != 0 || std::ferror(pcap_dump_file(d)) != 0;
    if (failed) {
      err = core::Error{core::kExitIoError, fmt::format("writing capture '{}' failed: {}", path_,
                                                        std::strerror(errno))};
    }
    pcap_dump_close(d);
    dumper_ = nullptr;
  }
  if (dead_ != nullptr) {
    pcap_close(static_cast<pcap_t*>(dead_));
    dead_ = nullptr;
  }
  return err;
}

}  // namespace cndt::pcap
