#include "cndt/sim/lidar_sim.hpp"

#include <fmt/format.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <numbers>

#include "cndt/core/bytes.hpp"
#include "cndt/pcap/pcap_writer.hpp"
#include "cndt/sim/random.hpp"
#include "cndt/vlp16/calibration.hpp"
#include "cndt/vlp16/packet.hpp"

namespace cndt::sim {
namespace {

constexpr std::int64_t kSequenceNs = 55'296;
constexpr std::int64_t kFiringNs = 2'304;
constexpr std::int64_t kHourNs = 3'600'000'000'000;
constexpr double kDeg = std::numbers::pi / 180.0;

enum Stream : std::uint64_t {
  kNoise = 1,
  kDrop = 2,
  kDropout = 3,
  kRefl = 4,
  kJitter = 5,
  kRotor = 6
};

std::uint16_t encode_range(double r, double max_range) {
  if (r <= 0.0 || r > max_range) return 0;
  return static_cast<std::uint16_t>(std::min(65535.0, std::round(r / 0.002)));
}

}  // namespace

LidarSimulator::LidarSimulator(const Scene& scene, const LidarSimOptions& options)
    : scene_(scene),
      options_(options),
      period_ns_(options.dual ? 12 * kSequenceNs : 24 * kSequenceNs),
      end_ns_(static_cast<std::int64_t>(options.duration_s * 1e9)),
      rotor0_deg_(360.0 * uniform(options.seed, kRotor, 0)) {
  const auto& t = vlp16::laser_table(vlp16::Model::kVlp16);
  for (std::size_t k = 0; k < 16; ++k) {
    cos_el_[k] = std::cos(t.elevation_deg[k] * kDeg);
    sin_el_[k] = std::sin(t.elevation_deg[k] * kDeg);
    z_off_[k] = t.vertical_offset_m[k];
  }
}

double LidarSimulator::rotor_deg(std::int64_t t_rel_ns) const {
  const double deg = rotor0_deg_ + options_.rpm * 6.0 * static_cast<double>(t_rel_ns) * 1e-9;
  return std::fmod(deg, 360.0);
}

namespace {
// Whether time t_rel_ns after the start falls in the options' outage.
bool in_outage(const LidarSimOptions& o, std::int64_t t_rel_ns) {
  const double t = static_cast<double>(t_rel_ns) * 1e-9;
  return o.outage_s > 0 && t >= o.outage_start_s && t < o.outage_start_s + o.outage_s;
}
}  // namespace

bool LidarSimulator::next(SimPacket& packet, std::vector<TruePoint>* truth) {
  const std::int64_t t0 = static_cast<std::int64_t>(next_index_) * period_ns_;
  if (t0 >= end_ns_) return false;
  packet.index = next_index_++;
  const bool stepped =
      options_.clock_step_s != 0.0 && static_cast<double>(t0) * 1e-9 >= options_.clock_step_at_s;
  packet.clock_offset_ns = stepped ? std::llround(options_.clock_step_s * 1e9) : 0;
  packet.sensor_time_ns = options_.start_time_ns + t0 + packet.clock_offset_ns;
  packet.dropped = (options_.drop_rate > 0 &&
                    uniform(options_.seed, kDrop, packet.index) < options_.drop_rate) ||
                   in_outage(options_, t0);
  // A receiver stamps the packet a little after its last firing.
  packet.capture_time_ns =
      options_.start_time_ns + t0 + period_ns_ + 150'000 +
      static_cast<std::int64_t>(100'000 * uniform(options_.seed, kJitter, packet.index));
  auto& p = packet.payload;
  core::MutableByteSpan bytes(p);
  scene_.movers_at(static_cast<double>(t0) * 1e-9, movers_);
  const int groups = options_.dual ? 6 : 12;
  for (int g = 0; g < groups; ++g) {
    const int first_block = options_.dual ? 2 * g : g;
    const std::int64_t t_block = t0 + 2 * g * kSequenceNs;
    const auto az = static_cast<std::uint16_t>(
        static_cast<long>(std::lround(rotor_deg(t_block) * 100.0)) % 36000);
    for (int b = first_block; b < first_block + (options_.dual ? 2 : 1); ++b) {
      const auto off = static_cast<std::size_t>(b) * vlp16::kBlockSize;
      core::store_le16(bytes, off, vlp16::kBlockFlagUpper);
      core::store_le16(bytes, off + 2, az);
    }
    for (int s = 0; s < 2; ++s) {
      const std::size_t rec = static_cast<std::size_t>(first_block) * vlp16::kBlockSize + 4 +
                              static_cast<std::size_t>(s) * 48;
      const std::size_t pair = options_.dual ? rec + vlp16::kBlockSize : rec;
      fire_sequence(t_block + s * kSequenceNs, 2 * g + s, rec, pair, packet, truth);
    }
  }
  const std::int64_t toh_ns = packet.sensor_time_ns % kHourNs;
  core::store_le32(bytes, vlp16::kTimestampOffset, static_cast<std::uint32_t>(toh_ns / 1000));
  p[vlp16::kReturnModeOffset] = options_.dual ? 0x39 : 0x37;
  p[vlp16::kProductIdOffset] = vlp16::kProductVlp16;
  return true;
}

void LidarSimulator::fire_sequence(std::int64_t t_ns, int sequence, std::size_t record_off,
                                   std::size_t pair_off, SimPacket& packet,
                                   std::vector<TruePoint>* truth) {
  // Ground-truth scan starts: the first sequence whose azimuth has passed the cut angle.
  const double az_deg = rotor_deg(t_ns);
  const int rel =
      static_cast<int>(std::lround(az_deg * 100.0) - options_.cut_azimuth + 36000) % 36000;
  const double t = static_cast<double>(t_ns) * 1e-9;
  if (last_rel_ < 0 || rel < last_rel_) {
    starts_.push_back(ScanStart{options_.start_time_ns + t_ns, scene_.sensor_pose(t)});
  }
  last_rel_ = rel;

  const Eigen::Isometry3d T = scene_.sensor_pose(t);
  const Eigen::Vector3d v = (scene_.sensor_pose(t + 1e-3).translation() - T.translation()) / 1e-3;
  auto bytes = core::MutableByteSpan(packet.payload);
  for (int k = 0; k < 16; ++k) {
    const auto ki = static_cast<std::size_t>(k);
    const std::int64_t tf = t_ns + k * kFiringNs;
    const double a = rotor_deg(tf) * kDeg;
    const Eigen::Vector3d dir(cos_el_[ki] * std::cos(a), -cos_el_[ki] * std::sin(a), sin_el_[ki]);
    const Eigen::Vector3d origin(0, 0, z_off_[ki]);
    Ray ray{T * origin + v * (static_cast<double>(k * kFiringNs) * 1e-9), T.linear() * dir};
    const std::uint64_t ray_id =
        (packet.index * 32 + static_cast<std::uint64_t>(sequence)) * 16 + ki;
    const RayReturns ret =
        scene_.world.cast(ray, options_.max_range_m + 1.0, movers_, options_.seed, ray_id);
    // Pick the returns the sensor reports: the strongest (single mode), or the last plus the
    // strongest, or the second strongest when the strongest is the last (dual mode).
    int last = ret.count - 1;
    int strongest = last;
    if (ret.count == 2 && ret.hits[0].strength > ret.hits[1].strength) strongest = 0;
    int other = ret.count == 2 ? (strongest == last ? 0 : strongest) : last;
    if (uniform(options_.seed, kDropout, ray_id) < options_.dropout) last = strongest = other = -1;
    auto encode = [&](int hit, std::size_t off, core::ReturnType type) {
      if (hit < 0) {
        core::store_le16(bytes, off, 0);
        bytes[off + 2] = 0;
        return;
      }
      const Hit& h = ret.hits[hit];
      const double r =
          h.range + options_.noise_m *
                        normal(options_.seed, kNoise, ray_id * 2 + static_cast<std::uint64_t>(hit));
      const std::uint16_t count = encode_range(r, options_.max_range_m);
      core::store_le16(bytes, off, count);
      const double refl =
          h.reflectivity +
          4.0 * normal(options_.seed, kRefl, ray_id * 2 + static_cast<std::uint64_t>(hit));
      bytes[off + 2] = static_cast<std::uint8_t>(std::clamp(std::round(refl), 0.0, 255.0));
      if (truth != nullptr && count != 0) {
        truth->push_back(TruePoint{packet.index, sequence, k, type, origin + r * dir, r});
      }
    };
    const std::size_t off = record_off + 3 * ki;
    if (!options_.dual) {
      encode(strongest, off, core::ReturnType::kSingle);
      continue;
    }
    if (last == other) {
      encode(last, off, core::ReturnType::kBoth);
      std::copy_n(packet.payload.begin() + static_cast<std::ptrdiff_t>(off), 3,
                  packet.payload.begin() + static_cast<std::ptrdiff_t>(pair_off + 3 * ki));
    } else {
      encode(last, off, core::ReturnType::kLast);
      encode(other, pair_off + 3 * ki, core::ReturnType::kStrongest);
    }
  }
}

std::array<std::uint8_t, 512> LidarSimulator::position_packet(std::int64_t time_ns) const {
  std::array<std::uint8_t, 512> p{};
  core::MutableByteSpan bytes(p);
  core::store_le32(bytes, 0xC6, static_cast<std::uint32_t>((time_ns % kHourNs) / 1000));
  p[0xCA] = 2;  // PPS locked
  const std::int64_t day_s = (time_ns / 1'000'000'000) % 86400;
  const std::int64_t cs = (time_ns / 10'000'000) % 100;
  char body[128];
  std::snprintf(body, sizeof body,
                "GPRMC,%02d%02d%02d.%02d,A,3725.1234,N,12208.5678,W,%05.1f,090.0,010126,,,A",
                static_cast<int>(day_s / 3600), static_cast<int>(day_s / 60 % 60),
                static_cast<int>(day_s % 60), static_cast<int>(cs), scene_.speed * 1.943844);
  unsigned sum = 0;
  for (const char* c = body; *c != '\0'; ++c) sum ^= static_cast<unsigned char>(*c);
  char sentence[160];
  const int n = std::snprintf(sentence, sizeof sentence, "$%s*%02X\r\n", body, sum);
  std::copy_n(sentence, n, p.begin() + 0xCE);
  return p;
}

core::Result<SimSummary> write_simulation(const Scene& scene, const LidarSimOptions& options,
                                          const std::string& dir) {
  namespace fs = std::filesystem;
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) {
    return core::Error{core::kExitIoError,
                       fmt::format("cannot create output folder '{}': {}", dir, ec.message())};
  }
  const std::string capture = (fs::path(dir) / "capture.pcap").string();
  auto writer = pcap::PcapWriter::create(capture, true);
  if (!writer) return writer.error();
  pcap::UdpEndpoints data_ep;
  pcap::UdpEndpoints pos_ep;
  pos_ep.source_port = pos_ep.dest_port = vlp16::kDefaultPositionPort;
  LidarSimulator sim(scene, options);
  SimSummary sum;
  sum.objects = scene.world.object_count();
  SimPacket packet;
  while (sim.next(packet)) {
    ++sum.packets;
    if (packet.dropped) {
      ++sum.dropped;
    } else {
      writer.value()->write_udp(std::chrono::nanoseconds(packet.capture_time_ns), data_ep,
                                core::ByteSpan(packet.payload));
    }
    // About 54 position packets a second, like the sensor (one per 14 data packets).
    if (packet.index % 14 == 7) {
      const std::int64_t t = packet.sensor_time_ns + sim.packet_period_ns() / 2;  // its clock
      const std::int64_t t_true = t - packet.clock_offset_ns;
      const auto pos = sim.position_packet(t);
      const bool lost = (options.drop_rate > 0 &&
                         uniform(options.seed, kDrop, ~packet.index) < options.drop_rate) ||
                        in_outage(options, t_true - options.start_time_ns);
      if (!lost) {
        writer.value()->write_udp(std::chrono::nanoseconds(t_true + 200'000), pos_ep,
                                  core::ByteSpan(pos));
        ++sum.position_packets;
      }
    }
  }
  if (auto err = writer.value()->close()) return *err;
  const std::string gt_path = (fs::path(dir) / "groundtruth.tum").string();
  std::ofstream gt(gt_path, std::ios::trunc);
  gt << "# time x y z qx qy qz qw  (T_world_sensor at each scan start; REP-103 sensor frame)\n";
  for (const auto& s : sim.scan_starts()) {
    const Eigen::Quaterniond q(s.pose.linear());
    const Eigen::Vector3d t = s.pose.translation();
    gt << fmt::format("{}.{:09d} {:.6f} {:.6f} {:.6f} {:.9f} {:.9f} {:.9f} {:.9f}\n",
                      s.time_ns / 1'000'000'000, s.time_ns % 1'000'000'000, t.x(), t.y(), t.z(),
                      q.x(), q.y(), q.z(), q.w());
  }
  gt.close();
  if (!gt) {
    return core::Error{core::kExitIoError, fmt::format("writing '{}' failed", gt_path)};
  }
  sum.scans = sim.scan_starts().size();
  return sum;
}

}  // namespace cndt::sim
