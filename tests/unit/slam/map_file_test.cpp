#include "cndt/slam/map_file.hpp"

#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <boost/crc.hpp>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <thread>

#include "temp_dir.hpp"

namespace cndt::slam {
namespace {

NdtMap random_map(std::size_t points, std::uint64_t seed, double window = 0.0) {
  MapOptions o;
  o.capacity = 400'000;
  o.window_radius = window;
  o.origin = {512'000.25, 5'400'000.5, 31.0};
  NdtMap map(o);
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-20.0, 20.0), cv(0.7, 1.0);
  for (std::size_t i = 0; i < points; ++i) {
    map.add({u(rng), u(rng), 0.1 * u(rng)}, cv(rng));
  }
  map.finalize();
  return map;
}

std::uint32_t crc32(const std::uint8_t* p, std::size_t n) {
  boost::crc_32_type c;
  c.process_bytes(p, n);
  return c.checksum();
}

// Recomputes both checksums after a deliberate edit, so that the record checks behind them run.
void reseal(std::vector<std::uint8_t>& f) {
  const std::size_t body = f.size() - kMapHeaderBytes - kMapTrailerBytes;
  core::store_le32(f, 72, crc32(f.data() + kMapHeaderBytes, body));
  core::store_le32(f, 76, crc32(f.data(), 76));
}

std::string decode_error(const std::vector<std::uint8_t>& f, std::size_t capacity = 64) {
  MapOptions o;
  o.capacity = capacity;
  auto r = decode_map(f, "test.cndtmap", o);
  return r ? std::string() : r.error().message;
}

// The CRC-32 docs/map_format.md specifies, bit by bit, to check the stored ones against.
std::uint32_t reference_crc32(const std::uint8_t* p, std::size_t n) {
  std::uint32_t c = 0xFFFFFFFFu;
  for (std::size_t i = 0; i < n; ++i) {
    c ^= p[i];
    for (int k = 0; k < 8; ++k) c = (c & 1u) != 0 ? (c >> 1) ^ 0xEDB88320u : c >> 1;
  }
  return c ^ 0xFFFFFFFFu;
}

TEST(MapFile, ChecksumsAreTheDocumentedCrc32) {
  const char* check = "123456789";
  ASSERT_EQ(reference_crc32(reinterpret_cast<const std::uint8_t*>(check), 9), 0xCBF43926u);
  const std::vector<std::uint8_t> f = encode_map(random_map(100, 9));
  const std::size_t body = f.size() - kMapHeaderBytes - kMapTrailerBytes;
  EXPECT_EQ(core::load_le32(f, 72), reference_crc32(f.data() + kMapHeaderBytes, body));
  EXPECT_EQ(core::load_le32(f, 76), reference_crc32(f.data(), 76));
}

TEST(MapFile, RoundTripIsExact) {
  NdtMap map = random_map(20'000, 1, 18.0);
  // Evicting leaves a voxel order that is not the insertion order.
  ASSERT_GT(map.evict_outside({6.0, 0.0, 0.0}), 100u);
  ASSERT_GT(map.size(), 1000u);
  const std::vector<std::uint8_t> bytes = encode_map(map);
  EXPECT_EQ(bytes.size(), kMapHeaderBytes + map.size() * kMapRecordBytes + kMapTrailerBytes);
  auto back = decode_map(bytes, "test.cndtmap", map.options());
  ASSERT_TRUE(back) << back.error().message;
  const NdtMap& m = back.value();
  EXPECT_EQ(m.options().voxel_size, map.options().voxel_size);
  EXPECT_EQ(m.options().origin, map.options().origin);
  ASSERT_EQ(m.size(), map.size());
  EXPECT_EQ(m.points(), map.points());
  for (std::size_t i = 0; i < m.size(); ++i) {
    const ndt::Voxel& a = map.grid().voxels()[i];
    const ndt::Voxel& b = m.grid().voxels()[i];
    ASSERT_EQ(a.key, b.key);
    ASSERT_EQ(a.count, b.count);
    ASSERT_EQ(a.consensus, b.consensus);
    ASSERT_EQ(a.sum, b.sum);
    ASSERT_EQ(a.sum_outer, b.sum_outer);
    ASSERT_EQ(a.has_gaussian, b.has_gaussian);
    if (a.has_gaussian) {
      ASSERT_EQ(map.grid().gaussians()[i].mean_vector(), m.grid().gaussians()[i].mean_vector());
      ASSERT_EQ(map.grid().gaussians()[i].inv_cov_matrix(),
                m.grid().gaussians()[i].inv_cov_matrix());
    }
    ASSERT_EQ(m.grid().index_of(a.key), static_cast<std::int64_t>(i));
  }
  EXPECT_EQ(encode_map(m), bytes);  // and byte for byte when written again
}

TEST(MapFile, EveryTruncationIsRefusedWithTheSection) {
  const NdtMap map = random_map(300, 2);
  const std::vector<std::uint8_t> f = encode_map(map);
  ASSERT_GT(map.size(), 5u);
  EXPECT_EQ(decode_error(f, 1000), "");
  for (std::size_t n = 0; n < f.size(); ++n) {
    const std::vector<std::uint8_t> cut(f.begin(), f.begin() + static_cast<std::ptrdiff_t>(n));
    const std::string e = decode_error(cut, 1000);
    ASSERT_NE(e, "") << "accepted a file cut at byte " << n;
    ASSERT_EQ(e.rfind("test.cndtmap: ", 0), 0u) << e;
    if (n < 8) {
      ASSERT_NE(e.find("not a cndt map file"), std::string::npos) << e;
    } else if (n < kMapHeaderBytes) {
      ASSERT_NE(e.find("truncated in the header"), std::string::npos) << e;
    } else {
      ASSERT_NE(e.find("truncated: the file is " + std::to_string(n) + " bytes"), std::string::npos)
          << e;
    }
  }
  std::vector<std::uint8_t> longer = f;
  longer.push_back(0);
  EXPECT_NE(decode_error(longer, 1000).find("trailing bytes"), std::string::npos);
}

TEST(MapFile, EveryFlippedBitIsRefusedWithTheSection) {
  const NdtMap map = random_map(40, 3);  // about 40 voxels: 4 kB, 32k flips
  std::vector<std::uint8_t> g = encode_map(map);
  const std::size_t body_end = g.size() - kMapTrailerBytes;
  for (std::size_t byte = 0; byte < g.size(); ++byte) {
    for (int bit = 0; bit < 8; ++bit) {
      const auto mask = static_cast<std::uint8_t>(1u << bit);
      g[byte] ^= mask;
      const std::string e = decode_error(g, 1000);
      g[byte] ^= mask;
      ASSERT_NE(e, "") << "accepted a flip of bit " << bit << " of byte " << byte;
      const char* expected = byte < 8                 ? "not a cndt map file"
                             : byte < kMapHeaderBytes ? "header checksum mismatch"
                             : byte < body_end        ? "voxel records checksum mismatch"
                                                      : "trailer";
      ASSERT_NE(e.find(expected), std::string::npos) << "byte " << byte << ": " << e;
    }
  }
}

TEST(MapFile, RecordsAreCheckedBehindTheChecksums) {
  const NdtMap map = random_map(300, 4);
  const std::vector<std::uint8_t> f = encode_map(map);
  const std::size_t r1 = kMapHeaderBytes + kMapRecordBytes;
  {
    std::vector<std::uint8_t> g = f;  // record 1 gets record 0's key
    std::copy(g.begin() + kMapHeaderBytes, g.begin() + kMapHeaderBytes + 12, g.begin() + r1);
    reseal(g);
    EXPECT_NE(decode_error(g, 1000).find("voxel record 1 (byte 176)"), std::string::npos)
        << decode_error(g, 1000);
    EXPECT_NE(decode_error(g, 1000).find("appears twice"), std::string::npos);
  }
  {
    std::vector<std::uint8_t> g = f;  // a NaN sum
    core::store_le_f64(g, r1 + 24, std::numeric_limits<double>::quiet_NaN());
    reseal(g);
    EXPECT_NE(decode_error(g, 1000).find("not finite"), std::string::npos);
  }
  {
    std::vector<std::uint8_t> g = f;  // another version
    core::store_le32(g, 8, 2);
    reseal(g);
    EXPECT_NE(decode_error(g, 1000).find("version 2; this build reads version 1"),
              std::string::npos);
  }
  MapOptions small;
  small.capacity = map.size() - 1;
  auto r = decode_map(f, "test.cndtmap", small);
  ASSERT_FALSE(r);
  EXPECT_EQ(r.error().code, core::kExitConfigError);
  EXPECT_NE(r.error().message.find("more than the configured capacity"), std::string::npos);
}

TEST(MapFile, SavesAndLoadsFilesWithClearErrors) {
  const test::TempDir dir;
  const std::string path = dir.file("a.cndtmap");
  const NdtMap map = random_map(5000, 5);
  ASSERT_FALSE(save_map_file(map, path));
  EXPECT_FALSE(std::filesystem::exists(path + ".tmp"));
  auto back = load_map_file(path, map.options());
  ASSERT_TRUE(back) << back.error().message;
  EXPECT_EQ(encode_map(back.value()), encode_map(map));
  auto missing = load_map_file(dir.file("none.cndtmap"), map.options());
  ASSERT_FALSE(missing);
  EXPECT_EQ(missing.error().code, core::kExitNoInput);
  const auto bad = save_map_file(map, dir.file("no/such/dir.cndtmap"));
  ASSERT_TRUE(bad);
  EXPECT_EQ(bad->code, core::kExitIoError);
  EXPECT_NE(bad->message.find("cannot create"), std::string::npos) << bad->message;
}

TEST(MapFile, AKilledSaveLeavesThePreviousFile) {
  // A child saves two different maps over one path in a loop; it is killed with SIGKILL as soon
  // as its temporary file shows up (mid-write), or at a random moment. Every time, the file
  // must load and be one of the two maps, whole.
  const test::TempDir dir;
  const std::string path = dir.file("k.cndtmap");
  const NdtMap a = random_map(60'000, 6), b = random_map(50'000, 7);
  ASSERT_NE(a.size(), b.size());
  ASSERT_FALSE(save_map_file(a, path));
  std::mt19937 rng(8);
  int killed_mid_write = 0;
  for (int round = 0; round < 8; ++round) {
    std::filesystem::remove(path + ".tmp");  // left by the previous kill
    const pid_t child = ::fork();
    ASSERT_GE(child, 0);
    if (child == 0) {
      for (int i = 0;; ++i) {
        if (save_map_file(i % 2 == 0 ? b : a, path)) ::_exit(3);
      }
    }
    if (round % 2 == 0) {  // wait for a temporary file, then kill at once
      const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(60);
      while (!std::filesystem::exists(path + ".tmp") &&
             std::chrono::steady_clock::now() < give_up) {
        std::this_thread::sleep_for(std::chrono::microseconds(50));
      }
    } else {
      std::this_thread::sleep_for(std::chrono::milliseconds(20 + rng() % 80));
    }
    ::kill(child, SIGKILL);
    int status = 0;
    ::waitpid(child, &status, 0);
    ASSERT_TRUE(WIFSIGNALED(status)) << "the saving child ended on its own: " << status;
    if (std::filesystem::exists(path + ".tmp")) ++killed_mid_write;
    auto m = load_map_file(path, a.options());
    ASSERT_TRUE(m) << m.error().message;
    ASSERT_TRUE(m.value().size() == a.size() || m.value().size() == b.size());
  }
  EXPECT_GT(killed_mid_write, 0);  // at least one kill landed while a temporary file existed
}

TEST(NdtMap, KeepsTheMeanConsensusAndEvictsOutsideTheWindow) {
  MapOptions o;
  o.capacity = 1000;
  o.window_radius = 10.0;
  NdtMap map(o);
  for (int i = 0; i < 5; ++i) map.add({0.1, 0.1, 0.05 * i}, i < 4 ? 1.0 : 0.5);
  for (int i = 0; i < 5; ++i) map.add({20.1, 0.1, 0.05 * i}, 0.8);
  map.finalize();
  ASSERT_EQ(map.size(), 2u);
  EXPECT_NEAR(map.grid().voxels()[0].consensus, 0.9, 1e-6);
  EXPECT_EQ(map.gaussians(), 2u);
  EXPECT_EQ(map.evict_outside({15.0, 0.0, 0.0}), 1u);  // the first voxel is 14.9 m away
  ASSERT_EQ(map.size(), 1u);
  EXPECT_EQ(map.grid().voxels()[0].key.x, 40);
  EXPECT_EQ(map.grid().index_of({40, 0, 0}), 0);
  EXPECT_EQ(map.grid().index_of({0, 0, 0}), -1);
  EXPECT_EQ(map.points(), 5u);
}

}  // namespace
}  // namespace cndt::slam
