// The cndt binary on bad input: one clear error line naming the file, and the documented exit
// code; never a crash or a silent empty result.
#include <gtest/gtest.h>

#include <array>
#include <cctype>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "cli_run.hpp"
#include "cndt/cli/cloud_io.hpp"
#include "cndt/core/bytes.hpp"
#include "cndt/slam/map_file.hpp"
#include "shared_data.hpp"
#include "temp_dir.hpp"

namespace {

using cndt::test::CliRun;
using cndt::test::run;

int error_lines(const std::string& out) {
  std::istringstream in(out);
  int n = 0;
  for (std::string line; std::getline(in, line);) n += line.rfind("cndt: error", 0) == 0 ? 1 : 0;
  return n;
}

TEST(CliBadInput, MissingFile) {
  const CliRun r = run("info /nonexistent/capture.pcap");
  EXPECT_EQ(r.code, 66) << r.output;
  EXPECT_EQ(error_lines(r.output), 1) << r.output;
  EXPECT_NE(r.output.find("/nonexistent/capture.pcap"), std::string::npos);
}

TEST(CliBadInput, DirectoryEmptyAndTextFiles) {
  cndt::test::TempDir dir;
  CliRun r = run("info " + dir.path().string());
  EXPECT_EQ(r.code, 66) << r.output;
  EXPECT_EQ(error_lines(r.output), 1) << r.output;
  std::ofstream(dir.file("empty.pcap")).close();
  r = run("decode " + dir.file("empty.pcap") + " --out " + dir.file("out"));
  EXPECT_EQ(r.code, 65) << r.output;
  EXPECT_NE(r.output.find("empty.pcap"), std::string::npos);
  std::ofstream(dir.file("readme.txt")) << "hello\n";
  r = run("info " + dir.file("readme.txt"));
  EXPECT_EQ(r.code, 65) << r.output;
  EXPECT_EQ(error_lines(r.output), 1) << r.output;
  EXPECT_NE(r.output.find("readme.txt"), std::string::npos);
}

TEST(CliBadInput, CaptureWithoutSensorDataIsNotASilentSuccess) {
  cndt::test::TempDir dir;
  // A capture of one second with every data packet lost leaves only position packets.
  CliRun r = run("sim --scene corridor --duration 0.3 --drop-rate 0.9 --out " + dir.file("s"));
  ASSERT_EQ(r.code, 0) << r.output;
  r = run("decode " + dir.file("s/capture.pcap") + " --out " + dir.file("d") + " --data-port 2999");
  EXPECT_EQ(r.code, 65) << r.output;
  EXPECT_NE(r.output.find("no scan"), std::string::npos) << r.output;
  r = run("info " + dir.file("s/capture.pcap") + " --data-port 2999");
  EXPECT_EQ(r.code, 65) << r.output;
}

// An HDL-64E capture: every packet is refused by model, and the error says so.
TEST(CliBadInput, ReplayOfAnUnsupportedSensorSaysWhyThereIsNoScan) {
  CNDT_REQUIRE_SHARED(path, "opendavinci-hdl64-wall/atwallshort.pcap");
  cndt::test::TempDir dir;
  for (const char* command : {"replay", "sweep"}) {
    const CliRun r = run(std::string(command) + " " + path + " --out " + dir.file(command));
    EXPECT_EQ(r.code, 65) << r.output;
    EXPECT_EQ(error_lines(r.output), 1) << r.output;
    EXPECT_NE(r.output.find("306 rejected: 306 unsupported_model"), std::string::npos) << r.output;
  }
}

TEST(CliUsage, BadOptionsAreUsageErrors) {
  EXPECT_EQ(run("").code, 2);
  EXPECT_EQ(run("info").code, 2);
  EXPECT_EQ(run("sim --out /tmp/x --rpm 500").code, 2);
  EXPECT_EQ(run("info x.pcap --model hdl64").code, 2);
  const CliRun help = run("info --help");
  EXPECT_EQ(help.code, 0);
  EXPECT_NE(help.output.find("--model"), std::string::npos);
}

TEST(CliRoundTrip, SimInfoDecode) {
  cndt::test::TempDir dir;
  CliRun r = run("sim --scene street --duration 1 --out " + dir.file("s"));
  ASSERT_EQ(r.code, 0) << r.output;
  r = run("info --json " + dir.file("s/capture.pcap"));
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_NE(r.output.find("\"model\": \"VLP-16\""), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("\"scans\": 11"), std::string::npos) << r.output;
  r = run("decode " + dir.file("s/capture.pcap") + " --out " + dir.file("d") + " --format ply");
  ASSERT_EQ(r.code, 0) << r.output;
  std::ifstream times(dir.file("d/times.txt"));
  int lines = 0;
  for (std::string l; std::getline(times, l);) lines += l[0] == '#' ? 0 : 1;
  EXPECT_EQ(lines, 11);
  std::ifstream ply(dir.file("d/000003.ply"));
  std::string magic;
  ply >> magic;
  EXPECT_EQ(magic, "ply");
}

// `--start-still`: the ground truth stands at its first position for that long, then moves.
TEST(CliRoundTrip, SimStartsFromRest) {
  EXPECT_EQ(run("sim --out /tmp/x --start-still -1").code, 2);
  cndt::test::TempDir dir;
  const CliRun r = run("sim --scene street --duration 1.5 --start-still 1 --out " + dir.file("s"));
  ASSERT_EQ(r.code, 0) << r.output;
  std::ifstream gt(dir.file("s/groundtruth.tum"));
  std::vector<std::string> positions;  // x y z of each line
  for (std::string l; std::getline(gt, l);) {
    if (l.empty() || l[0] == '#') continue;
    std::istringstream in(l);
    std::string t, x, y, z;
    in >> t >> x >> y >> z;
    positions.push_back(x + " " + y + " " + z);
  }
  ASSERT_GE(positions.size(), 15u);
  for (std::size_t i = 1; i < 10; ++i) EXPECT_EQ(positions[i], positions[0]) << i;
  EXPECT_NE(positions.back(), positions[0]);
}

TEST(CliReplay, WritesTrajectoryScansAndSummaryThatEvalReads) {
  cndt::test::TempDir dir;
  CliRun r = run("sim --scene street --duration 1.5 --out " + dir.file("s"));
  ASSERT_EQ(r.code, 0) << r.output;
  r = run("replay " + dir.file("s/capture.pcap") + " --out " + dir.file("r") + " --max-scans 6");
  ASSERT_EQ(r.code, 0) << r.output;
  std::ifstream tum(dir.file("r/trajectory.tum"));
  int poses = 0;
  for (std::string l; std::getline(tum, l);) poses += 1;
  EXPECT_EQ(poses, 5);  // one per scan but the first, a partial revolution
  std::ifstream csv(dir.file("r/scans.csv"));
  std::string header;
  std::getline(csv, header);
  EXPECT_EQ(header.rfind("time,cm,coarse_iterations,fine_iterations,voxels_before", 0), 0u);
  // Every scan has a row; the first says it was skipped (flag 32) and the others do not.
  std::vector<unsigned long> flags;
  for (std::string l; std::getline(csv, l);)
    flags.push_back(std::stoul(l.substr(l.rfind(',') + 1)));
  ASSERT_EQ(flags.size(), 6u);
  EXPECT_NE(flags[0] & 32UL, 0UL);
  for (std::size_t i = 1; i < flags.size(); ++i) EXPECT_EQ(flags[i] & 32UL, 0UL);
  std::stringstream summary;
  summary << std::ifstream(dir.file("r/summary.json")).rdbuf();
  for (const char* key : {"\"scans\": 6", "\"packets_ok\"", "\"packets_bad\": 0",
                          "\"scans_dropped\"", "\"odometry_ms_p50\"", "\"odometry_ms_p99\"",
                          "\"iterations_mean\"", "\"heap_allocations_in_odometry\"",
                          "\"peak_rss_mb\"", "\"wall_s\"", "\"mode\": \"consensus\""}) {
    EXPECT_NE(summary.str().find(key), std::string::npos) << key << " in " << summary.str();
  }
  r = run("eval --gt " + dir.file("s/groundtruth.tum") + " --est " + dir.file("r/trajectory.tum"));
  ASSERT_EQ(r.code, 0) << r.output;
  for (const char* key : {"\"ate_rmse_m\"", "\"matched\": 5", "\"start_aligned\"",
                          "\"height_error_end_m\"", "\"tilt_end_deg\""}) {
    EXPECT_NE(r.output.find(key), std::string::npos) << key << " in " << r.output;
  }
}

// The Figure 9 experiment on a capture: Cm of one scan against its held reference as the scan
// is moved away from its estimate. At 0 it is the Cm the replay reports for that scan.
TEST(CliSweep, CmOfAScanMovedFromItsEstimateAndBadRequestsNamed) {
  cndt::test::TempDir dir;
  CliRun r = run("sim --scene street --duration 1.5 --out " + dir.file("s"));
  ASSERT_EQ(r.code, 0) << r.output;
  const std::string capture = dir.file("s/capture.pcap");
  r = run("sweep " + capture + " --out " + dir.file("w") + " --scan 10 --steps 10");
  ASSERT_EQ(r.code, 0) << r.output;
  std::ifstream csv(dir.file("w/sweep.csv"));
  std::string line;
  std::getline(csv, line);
  EXPECT_EQ(line, "axis,perturbation,unit,cm,voxels_with_cv");
  std::vector<std::string> axes;
  std::vector<double> moved, cms;
  while (std::getline(csv, line)) {
    std::istringstream in(line);
    std::string axis, value, unit, cm;
    std::getline(in, axis, ',');
    std::getline(in, value, ',');
    std::getline(in, unit, ',');
    std::getline(in, cm, ',');
    EXPECT_EQ(unit, axis == "x" ? "m" : "deg") << line;
    axes.push_back(axis);
    moved.push_back(std::stod(value));
    cms.push_back(std::stod(cm));
    EXPECT_TRUE(cms.back() >= 0.0 && cms.back() <= 1.0) << line;
  }
  ASSERT_EQ(cms.size(), 22u);  // x, then roll: 0 to the largest move in 10 steps each
  EXPECT_EQ(axes.front(), "x");
  EXPECT_EQ(axes.back(), "roll");
  EXPECT_DOUBLE_EQ(moved[10], 2.0);
  EXPECT_DOUBLE_EQ(moved[21], 5.0);
  EXPECT_GT(cms[0], 0.5);
  EXPECT_EQ(cms[0], cms[11]);
  // 2 m along the street (its ground and facades still agree there) and 5 deg of roll.
  EXPECT_LT(cms[10], 0.8 * cms[0]);
  EXPECT_LT(cms[21], 0.5 * cms[0]);
  std::stringstream svg;
  svg << std::ifstream(dir.file("w/sweep.svg")).rdbuf();
  EXPECT_EQ(svg.str().rfind("<svg", 0), 0u);
  std::size_t charts = 0;
  for (auto at = svg.str().find("<polyline"); at != std::string::npos;
       at = svg.str().find("<polyline", at + 1)) {
    ++charts;
  }
  EXPECT_EQ(charts, 2u);
  // The replay's Cm of that scan (row 10 of scans.csv) is the sweep's at 0.
  r = run("replay " + capture + " --out " + dir.file("r") + " --max-scans 11");
  ASSERT_EQ(r.code, 0) << r.output;
  std::ifstream scans(dir.file("r/scans.csv"));
  for (int i = 0; i <= 11; ++i) std::getline(scans, line);
  const std::string replay_cm =
      line.substr(line.find(',') + 1, line.find(',', line.find(',') + 1) - line.find(',') - 1);
  EXPECT_DOUBLE_EQ(std::stod(replay_cm), cms[0]) << line;

  // Scans that cannot be swept, and axes that do not exist: named, with the exit code.
  r = run("sweep " + capture + " --out " + dir.file("w2") + " --scan 40");
  EXPECT_EQ(r.code, 65) << r.output;
  EXPECT_NE(r.output.find("has 16 scans: --scan 40 must be below that"), std::string::npos)
      << r.output;
  r = run("sweep " + capture + " --out " + dir.file("w2") + " --scan 0");
  EXPECT_EQ(r.code, 65) << r.output;
  EXPECT_NE(r.output.find("was skipped"), std::string::npos) << r.output;
  r = run("sweep " + capture + " --out " + dir.file("w2") + " --scan 1");
  EXPECT_EQ(r.code, 65) << r.output;
  EXPECT_NE(r.output.find("no reference yet"), std::string::npos) << r.output;
  EXPECT_EQ(error_lines(r.output), 1) << r.output;
  r = run("sweep " + capture + " --out " + dir.file("w2") + " --axes x,twist");
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("twist"), std::string::npos) << r.output;
}

// Every text a replay writes, lower-cased: a NaN or an infinity shows as "nan" or "inf".
std::string replay_outputs(const std::string& dir) {
  std::string all;
  for (const char* f : {"trajectory.tum", "scans.csv", "summary.json", "can.log"}) {
    std::stringstream s;
    s << std::ifstream(dir + "/" + f).rdbuf();
    all += s.str();
  }
  for (char& c : all) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return all;
}

// Scan flags, one per row of scans.csv (the last field).
std::vector<unsigned long> scan_flags(const std::string& dir) {
  std::ifstream csv(dir + "/scans.csv");
  std::string line;
  std::getline(csv, line);
  std::vector<unsigned long> flags;
  while (std::getline(csv, line)) flags.push_back(std::stoul(line.substr(line.rfind(',') + 1)));
  return flags;
}

// Input the odometry cannot make a good pose of: a clear error, or poses flagged and reported
// with Cm 0; never a NaN or an infinity in any output.
TEST(CliReplay, BadInputGivesAnErrorOrFlaggedPosesAndNeverNaN) {
  cndt::test::TempDir dir;
  // A capture with no packet at all: an error naming it, exit 65, an empty result.
  {
    std::ofstream pcap(dir.file("empty.pcap"), std::ios::binary);
    const std::array<std::uint32_t, 6> header = {0xA1B2C3D4u, 0x00040002u, 0, 0, 65535, 1};
    pcap.write(reinterpret_cast<const char*>(header.data()), sizeof(header));
  }
  CliRun r = run("replay " + dir.file("empty.pcap") + " --out " + dir.file("e"));
  EXPECT_EQ(r.code, 65) << r.output;
  EXPECT_NE(r.output.find("no scan in"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("empty.pcap"), std::string::npos) << r.output;
  EXPECT_EQ(scan_flags(dir.file("e")).size(), 0u);
  // 0.1 s: a partial revolution (skipped) and a second one cut by the end of the capture.
  ASSERT_EQ(run("sim --scene street --duration 0.1 --out " + dir.file("short")).code, 0);
  r = run("replay " + dir.file("short/capture.pcap") + " --out " + dir.file("s"));
  EXPECT_EQ(r.code, 0) << r.output;
  auto flags = scan_flags(dir.file("s"));
  ASSERT_EQ(flags.size(), 2u);
  EXPECT_NE(flags[0] & 32UL, 0UL);  // skipped
  EXPECT_NE(flags[1] & 16UL, 0UL);  // incomplete
  // Nine packets in ten lost: scans of a few hundred points, too few to match, or matched but
  // flagged degenerate with Cm 0, or (where the data resumes mid-revolution after a gap) not
  // matched at all.
  ASSERT_EQ(run("sim --scene street --duration 2 --drop-rate 0.9 --out " + dir.file("sparse")).code,
            0);
  r = run("replay " + dir.file("sparse/capture.pcap") + " --out " + dir.file("p"));
  EXPECT_EQ(r.code, 0) << r.output;
  flags = scan_flags(dir.file("p"));
  ASSERT_GE(flags.size(), 15u);
  int flagged = 0;
  for (unsigned long f : flags) flagged += (f & (4UL | 8UL | 32UL)) != 0 ? 1 : 0;
  EXPECT_GE(flagged, static_cast<int>(flags.size()) - 2);
  // A corridor: walls, floor and ceiling around the sensor; most poses flagged degenerate.
  ASSERT_EQ(run("sim --scene corridor --duration 3 --out " + dir.file("corridor")).code, 0);
  r = run("replay " + dir.file("corridor/capture.pcap") + " --out " + dir.file("c"));
  EXPECT_EQ(r.code, 0) << r.output;
  for (const char* d : {"e", "s", "p", "c"}) {
    const std::string out = replay_outputs(dir.file(d));
    EXPECT_EQ(out.find("nan"), std::string::npos) << d;
    EXPECT_EQ(out.find("inf"), std::string::npos) << d;
  }
}

// A path shorter than 20 m holds no 10 m segment twice: the segment errors are null, not 0, and
// a warning says why; the ATE is still measured.
TEST(CliEval, AShortPathHasNullSegmentErrors) {
  cndt::test::TempDir dir;
  std::ofstream gt(dir.file("gt.tum"));
  std::ofstream est(dir.file("est.tum"));
  for (int i = 0; i < 30; ++i) {  // 14.5 m
    gt << i * 0.1 << " " << i * 0.5 << " 0 0 0 0 0 1\n";
    est << i * 0.1 << " " << i * 0.51 << " 0 0 0 0 0 1\n";
  }
  gt.close();
  est.close();
  const CliRun r = run("eval --gt " + dir.file("gt.tum") + " --est " + dir.file("est.tum"));
  EXPECT_EQ(r.code, 0) << r.output;
  EXPECT_NE(r.output.find("\"rte_percent\": null"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("\"rre_deg_per_m\": null"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("shorter than 20 m"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("\"ate_rmse_m\": 0.0000"), std::string::npos) << r.output;
}

TEST(CliEval, BadTrajectoryFilesNameFileAndLine) {
  cndt::test::TempDir dir;
  std::ofstream(dir.file("gt.tum")) << "# header\n1.0 0 0 0 0 0 0 1\n2.0 1 0 0 0 0 0 1\n";
  std::ofstream(dir.file("bad.tum")) << "1.0 0 0 0 0 0 0 1\n2.0 1 0 0 0 0\n";
  CliRun r = run("eval --gt " + dir.file("gt.tum") + " --est " + dir.file("bad.tum"));
  EXPECT_EQ(r.code, 65) << r.output;
  EXPECT_NE(r.output.find("bad.tum:2"), std::string::npos) << r.output;
  r = run("eval --gt " + dir.file("missing.tum") + " --est " + dir.file("gt.tum"));
  EXPECT_EQ(r.code, 66) << r.output;
}

}  // namespace

namespace {

// Scan folders as replay input: what `cndt decode` writes (PCD with times.txt) replays, and a
// cut PCD or an empty folder is one clear error naming it.
TEST(CliReplay, CloudFoldersReplayAndBadCloudsAreNamed) {
  cndt::test::TempDir dir;
  CliRun r = run("sim --scene street --duration 1 --out " + dir.file("s"));
  ASSERT_EQ(r.code, 0) << r.output;
  r = run("decode " + dir.file("s/capture.pcap") + " --out " + dir.file("d") + " --format pcd");
  ASSERT_EQ(r.code, 0) << r.output;
  r = run("replay " + dir.file("d") + " --out " + dir.file("r") + " --max-scans 6");
  ASSERT_EQ(r.code, 0) << r.output;
  std::ifstream tum(dir.file("r/trajectory.tum"));
  std::string first;
  std::getline(tum, first);
  std::ifstream times(dir.file("d/times.txt"));
  std::string line, file, stamp;
  while (std::getline(times, line) && line[0] == '#') {
  }
  std::istringstream(line) >> file >> stamp;
  EXPECT_EQ(first.substr(0, 10), stamp.substr(0, 10)) << first << " vs " << line;
  int poses = 1;
  for (std::string l; std::getline(tum, l);) ++poses;
  EXPECT_EQ(poses, 6);

  // Cut the third cloud in the middle of its points.
  std::filesystem::resize_file(dir.file("d/000002.pcd"), 2000);
  r = run("replay " + dir.file("d") + " --out " + dir.file("r2"));
  EXPECT_EQ(r.code, 65) << r.output;
  EXPECT_EQ(error_lines(r.output), 1) << r.output;
  EXPECT_NE(r.output.find("000002.pcd"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("ends at point"), std::string::npos) << r.output;

  std::filesystem::create_directories(dir.file("empty"));
  r = run("replay " + dir.file("empty") + " --out " + dir.file("r3"));
  EXPECT_EQ(r.code, 65) << r.output;
  EXPECT_NE(r.output.find("no .bin or .pcd"), std::string::npos) << r.output;

  // One cloud where the folder belongs: a usage error that names the folder to pass.
  r = run("replay " + dir.file("d/000001.pcd") + " --out " + dir.file("r4"));
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_EQ(error_lines(r.output), 1) << r.output;
  EXPECT_NE(r.output.find("is one cloud file"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("'" + dir.file("d") + "'"), std::string::npos) << r.output;
}

}  // namespace

namespace {

std::size_t field(const std::string& text, const std::string& key) {
  const auto at = text.find(key + ": ");
  if (at == std::string::npos) return 0;
  return std::stoul(text.substr(at + key.size() + 2));
}

TEST(CliMap, InfoAndExportsAgreeAndTheExportsParseBack) {
  const cndt::test::TempDir dir;
  cndt::slam::MapOptions o;
  o.capacity = 100'000;
  cndt::slam::NdtMap map(o);
  for (int i = 0; i < 200; ++i) {  // a floor, a wall, and a few single points
    for (int j = 0; j < 40; ++j) {
      map.add({0.05 * i, 0.05 * j, 0.01 * ((i * 7 + j * 3) % 5)}, 0.9);
      map.add({0.05 * i, 2.0 + 0.01 * ((i + j) % 3), 0.05 * j}, 0.8);
    }
  }
  for (int k = 0; k < 7; ++k) map.add({30.0 + 3 * k, 5.0, 1.0}, 1.0);
  map.finalize();
  const std::string file = dir.file("m.cndtmap");
  ASSERT_FALSE(cndt::slam::save_map_file(map, file));

  const CliRun info = run("map info " + file);
  ASSERT_EQ(info.code, 0) << info.output;
  EXPECT_EQ(field(info.output, "voxels"), map.size());
  const std::size_t gaussians = field(info.output, "voxels with a Gaussian");
  EXPECT_EQ(gaussians, map.gaussians());
  EXPECT_LT(gaussians, map.size());  // the single points have no Gaussian
  EXPECT_EQ(field(info.output, "points"), map.points());

  // PLY, read by hand: header lines, then 24-byte little-endian vertices.
  const std::string ply = dir.file("m.ply");
  const CliRun e1 = run("map export " + file + " --ply " + ply);
  ASSERT_EQ(e1.code, 0) << e1.output;
  std::ifstream in(ply, std::ios::binary);
  std::string line;
  std::vector<std::string> props;
  std::size_t vertices = 0;
  while (std::getline(in, line) && line != "end_header") {
    if (line.rfind("element vertex ", 0) == 0) vertices = std::stoul(line.substr(15));
    if (line.rfind("property ", 0) == 0) props.push_back(line.substr(9));
  }
  ASSERT_EQ(line, "end_header");
  EXPECT_EQ(vertices, gaussians);
  EXPECT_EQ(props, (std::vector<std::string>{"float x", "float y", "float z", "float size",
                                             "float cv", "uint count"}));
  std::vector<std::uint8_t> body((std::istreambuf_iterator<char>(in)),
                                 std::istreambuf_iterator<char>());
  ASSERT_EQ(body.size(), vertices * 24);
  std::size_t k = 0;
  for (std::size_t i = 0; i < map.grid().size(); ++i) {
    const auto& v = map.grid().voxels()[i];
    if (!v.has_gaussian) continue;
    const auto& g = map.grid().gaussians()[i];
    EXPECT_EQ(cndt::core::load_le_f32(body, k * 24), static_cast<float>(g.mean[0]));
    EXPECT_EQ(cndt::core::load_le_f32(body, k * 24 + 8), static_cast<float>(g.mean[2]));
    EXPECT_NEAR(cndt::core::load_le_f32(body, k * 24 + 16), v.consensus, 1e-6);
    EXPECT_EQ(cndt::core::load_le32(body, k * 24 + 20), v.count);
    ++k;
  }

  // PCD, read with the replay's PCD reader.
  const std::string pcd = dir.file("m.pcd");
  const CliRun e2 = run("map export " + file + " --pcd " + pcd);
  ASSERT_EQ(e2.code, 0) << e2.output;
  cndt::core::Scan scan(100'000);
  ASSERT_FALSE(cndt::cli::read_cloud(pcd, scan));
  ASSERT_EQ(scan.points.size(), gaussians);
  EXPECT_EQ(scan.points[0].x, cndt::core::load_le_f32(body, 0));

  // Bad input: not a map, a damaged map, no output format.
  const std::string text = dir.file("notes.txt");
  std::ofstream(text) << "not a map\n";
  const CliRun bad = run("map info " + text);
  EXPECT_EQ(bad.code, 65);
  EXPECT_NE(bad.output.find("not a cndt map file"), std::string::npos) << bad.output;
  std::filesystem::resize_file(file, std::filesystem::file_size(file) - 1);
  const CliRun cut = run("map export " + file + " --ply " + ply);
  EXPECT_EQ(cut.code, 65);
  EXPECT_NE(cut.output.find("truncated"), std::string::npos) << cut.output;
  EXPECT_EQ(run("map export " + file).code, 2);
}

}  // namespace

namespace {

int lines(const std::string& path) {
  std::ifstream in(path);
  int n = 0;
  for (std::string l; std::getline(in, l);) ++n;
  return n;
}

TEST(CliReplay, MapperSavesAMapThatASecondReplayLocalizesIn) {
  cndt::test::TempDir dir;
  // Eight scans: enough for keyframes and a map, and quick under the sanitizers.
  CliRun r = run("sim --scene street --duration 1 --out " + dir.file("s"));
  ASSERT_EQ(r.code, 0) << r.output;
  r = run("replay " + dir.file("s/capture.pcap") + " --out " + dir.file("a") +
          " --max-scans 8 --save-map " + dir.file("a.cndtmap"));
  ASSERT_EQ(r.code, 0) << r.output;
  const int poses = lines(dir.file("a/trajectory.tum"));
  EXPECT_EQ(poses, 7);  // the first scan, a partial revolution, has none
  EXPECT_EQ(lines(dir.file("a/odometry.tum")), poses);
  EXPECT_EQ(lines(dir.file("a/refined.tum")), poses);  // every scan, once its keyframe closed
  EXPECT_EQ(lines(dir.file("a/refined.csv")), poses + 1);
  std::stringstream summary;
  summary << std::ifstream(dir.file("a/summary.json")).rdbuf();
  EXPECT_NE(summary.str().find("\"mapper\": true"), std::string::npos) << summary.str();
  const CliRun info = run("map info " + dir.file("a.cndtmap"));
  ASSERT_EQ(info.code, 0) << info.output;
  EXPECT_GT(field(info.output, "voxels with a Gaussian"), 2000u);

  // The same capture localized in that map, frozen, from a given start pose.
  r = run("replay " + dir.file("s/capture.pcap") + " --out " + dir.file("b") +
          " --max-scans 8 --map " + dir.file("a.cndtmap") + " --initial-pose 0,0,0,0,0,0");
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_NE(r.output.find("localizing in"), std::string::npos) << r.output;
  EXPECT_EQ(lines(dir.file("b/refined.tum")), poses);
  const CliRun info2 = run("map info " + dir.file("a.cndtmap"));
  EXPECT_EQ(info2.output, info.output);  // a frozen map is not written

  // Bad input: a pose that is not six numbers, a map that is not a map.
  r = run("replay " + dir.file("s/capture.pcap") + " --out " + dir.file("c") + " --map " +
          dir.file("a.cndtmap") + " --initial-pose 1,2,3");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.output.find("--initial-pose '1,2,3'"), std::string::npos) << r.output;
  r = run("replay " + dir.file("s/capture.pcap") + " --out " + dir.file("c") + " --map " +
          dir.file("s/groundtruth.tum"));
  EXPECT_EQ(r.code, 65);
  EXPECT_NE(r.output.find("not a cndt map file"), std::string::npos) << r.output;
}

}  // namespace
