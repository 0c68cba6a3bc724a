// The configuration loader: defaults, the documented file, and precise errors.
#include "cndt/config/config.hpp"

#include <gtest/gtest.h>

#include <fstream>
#include <sstream>

namespace cndt::config {
namespace {

TEST(Config, DocumentedDefaultsLoadToTheDefaults) {
  const std::string text = documented_defaults();
  auto c = parse_config(text, "defaults.toml");
  ASSERT_TRUE(c) << c.error().message;
  EXPECT_EQ(effective(c.value()), effective(Config{}));
  // Every key appears in the documentation.
  std::istringstream in(effective(Config{}));
  for (std::string line; std::getline(in, line);) {
    const std::string key = line.substr(line.find('.') + 1, line.find(' ') - line.find('.') - 1);
    EXPECT_NE(text.find("\n" + key + " = "), std::string::npos) << key;
  }
}

TEST(Config, ShippedFileIsTheDocumentedDefaults) {
  std::ifstream in(std::string(CNDT_SOURCE_DIR) + "/config/cndtd.toml");
  ASSERT_TRUE(in);
  std::ostringstream ss;
  ss << in.rdbuf();
  EXPECT_EQ(ss.str(), documented_defaults())
      << "config/cndtd.toml is out of date: regenerate it with `cndtd --print-config > "
         "config/cndtd.toml`";
}

TEST(Config, ValuesAreRead) {
  auto c = parse_config(R"(
[sensor]
source = "pcap"
pcap = "/tmp/x.pcap"
data_port = 2369
[odometry]
eta = 0.8
voxel_size_m = 1        # an integer where a number is expected is fine
[mapper]
enabled = true
initial_pose = [1, 2, 3, 0, 0, 90.5]
[can]
base_id = 0x400
[udp]
destinations = ["127.0.0.1:5600", "[::1]:5601"]
)",
                        "t.toml");
  ASSERT_TRUE(c) << c.error().message;
  EXPECT_EQ(c.value().sensor.source, "pcap");
  EXPECT_EQ(c.value().sensor.data_port, 2369);
  EXPECT_DOUBLE_EQ(c.value().odometry.eta, 0.8);
  EXPECT_DOUBLE_EQ(c.value().odometry.voxel_size_m, 1.0);
  EXPECT_TRUE(c.value().mapper.enabled);
  EXPECT_DOUBLE_EQ(c.value().mapper.initial_pose[5], 90.5);
  EXPECT_EQ(c.value().can.base_id, 0x400);
  ASSERT_EQ(c.value().udp.destinations.size(), 2u);
}

TEST(Config, EveryProblemIsReportedWithItsLine) {
  auto c = parse_config(
      "[sensor]\n"               // 1
      "data_prot = 2368\n"       // 2: unknown key, misspelt
      "[odometry]\n"             // 3
      "eta = \"high\"\n"         // 4: wrong type
      "voxel_size_m = 50.0\n"    // 5: out of range
      "mode = \"fast\"\n"        // 6: not a choice
      "[mapper]\n"               // 7
      "initial_pose = [1, 2]\n"  // 8: wrong size
      "[plugins]\n"              // 9: unknown section
      "x = 1\n",
      "bad.toml");
  ASSERT_FALSE(c);
  EXPECT_EQ(c.error().code, core::kExitConfigError);
  const std::string& m = c.error().message;
  EXPECT_NE(m.find("bad.toml:2:1: sensor.data_prot: unknown key (did you mean 'data_port'?)"),
            std::string::npos)
      << m;
  EXPECT_NE(m.find("bad.toml:4:7: odometry.eta: expected a number, got a string"),
            std::string::npos)
      << m;
  EXPECT_NE(m.find("bad.toml:5:16: odometry.voxel_size_m: 50 is out of range [0.05, 10] (m)"),
            std::string::npos)
      << m;
  EXPECT_NE(m.find("bad.toml:6:8: odometry.mode: 'fast' is not one of consensus, naive"),
            std::string::npos)
      << m;
  EXPECT_NE(m.find("bad.toml:8:16: mapper.initial_pose: expected 6 numbers, got 2"),
            std::string::npos)
      << m;
  EXPECT_NE(m.find("bad.toml:9:2: plugins: unknown section"), std::string::npos) << m;
  EXPECT_EQ(std::count(m.begin(), m.end(), '\n'), 5) << m;
}

TEST(Config, RelationsSyntaxAndMissingFiles) {
  auto c =
      parse_config("[sensor]\nmin_range_m = 5.0\nmax_range_m = 2.0\nsource = \"pcap\"\n", "r.toml");
  ASSERT_FALSE(c);
  EXPECT_NE(c.error().message.find("r.toml:3:15: sensor.max_range_m: must be greater than"),
            std::string::npos)
      << c.error().message;
  EXPECT_NE(c.error().message.find("sensor.pcap: source = \"pcap\" needs the capture file"),
            std::string::npos)
      << c.error().message;
  c = parse_config("[sensor\nx = 1\n", "s.toml");
  ASSERT_FALSE(c);
  EXPECT_NE(c.error().message.find("s.toml:1:"), std::string::npos) << c.error().message;
  EXPECT_NE(c.error().message.find("TOML syntax error"), std::string::npos);
  c = parse_config("[udp]\ndestinations = [\"localhost\"]\n", "u.toml");
  ASSERT_FALSE(c);
  EXPECT_NE(c.error().message.find("'localhost' is not ADDRESS:PORT"), std::string::npos);
  c = load_config("/nonexistent/cndtd.toml");
  ASSERT_FALSE(c);
  EXPECT_EQ(c.error().code, core::kExitNoInput);
}

}  // namespace
}  // namespace cndt::config
