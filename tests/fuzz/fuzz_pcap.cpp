// Any file offered as a capture: PcapSource opens it or refuses it with an error, and reads it
// to the end without crashing, whatever the records hold.
#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "cndt/pcap/pcap_source.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  char path[] = "/tmp/cndt-fuzz-pcap-XXXXXX";
  const int fd = mkstemp(path);
  if (fd < 0) return 0;
  if (write(fd, data, size) != static_cast<ssize_t>(size)) {
    close(fd);
    unlink(path);
    return 0;
  }
  close(fd);
  auto src = cndt::pcap::PcapSource::open(path, {});
  if (src) {
    cndt::io::SourcePacket p;
    std::size_t n = 0;
    while (src.value()->next(p) == cndt::io::NextResult::kPacket) {
      if (p.payload.size() > 65535) std::abort();
      ++n;
    }
    if (n > src.value()->stats().records) std::abort();
  } else if (src.error().message.empty()) {
    std::abort();
  }
  unlink(path);
  return 0;
}
