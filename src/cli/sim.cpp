#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cmath>

#include "cndt/cli/commands.hpp"
#include "cndt/output/pose_message.hpp"
#include "cndt/sim/lidar_sim.hpp"

namespace cndt::cli {

void register_sim(CLI::App& app, SimArgs& a) {
  auto* cmd = app.add_subcommand(
      "sim",
      "Simulate a VLP-16 driving through a synthetic world: writes capture.pcap (the "
      "sensor's exact wire format, with motion skew, range noise and 2 mm quantisation) "
      "and groundtruth.tum (sensor pose at each scan start). Deterministic per seed.");
  cmd->add_option("--scene", a.scene,
                  "street (8 m/s between buildings), campus (4 m/s, winding, trees), corridor "
                  "(1.2 m/s indoors, few features) or loop (7 m/s around a block)")
      ->capture_default_str()
      ->check(CLI::IsMember({"street", "campus", "corridor", "loop"}));
  cmd->add_option("--duration", a.duration_s, "Seconds of driving")
      ->capture_default_str()
      ->check(CLI::Range(0.1, 86400.0));
  cmd->add_option("--out", a.out_dir, "Output folder (created if missing)")->required();
  cmd->add_option("--seed", a.seed, "World, traffic and noise seed")->capture_default_str();
  cmd->add_option("--world-seed", a.world_seed,
                  "Seed of the static world alone (default: --seed): captures with one world "
                  "seed and different --seed share the world and differ in movers and noise");
  cmd->add_option("--movers", a.movers, "Moving objects (cars, or pedestrians indoors/campus)")
      ->capture_default_str()
      ->check(CLI::Range(0, 64));
  cmd->add_option("--drop-rate", a.drop_rate, "Fraction of packets lost, 0..0.9")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 0.9));
  cmd->add_option("--outage", a.outage,
                  "START SECONDS: nothing arrives for SECONDS from START seconds into the drive "
                  "(a data outage; the ground truth keeps every scan)")
      ->expected(2);
  cmd->add_option("--stop", a.stop,
                  "AT SECONDS: at AT seconds into the drive the vehicle brakes to a standstill "
                  "(over 3 s), stands for SECONDS and pulls away again (over 3 s)")
      ->expected(2);
  cmd->add_option("--start-still", a.start_still_s,
                  "SECONDS: the vehicle stands for SECONDS at the start and then pulls away "
                  "(over 3 s), as a drive from a parked car or a robot at rest does (default 0: "
                  "at speed from the first scan)")
      ->check(CLI::Range(0.0, 3600.0));
  cmd->add_option("--clock-step", a.clock_step,
                  "AT SECONDS: from AT seconds into the drive the sensor's clock reads SECONDS "
                  "more (negative: less), as when a time source takes over; packets keep coming "
                  "on time, and the ground truth stays on the true clock")
      ->expected(2);
  cmd->add_option("--speed", a.speed,
                  "Mean speed, m/s (default: the scene's own; it varies +-20 % over the drive)")
      ->check(CLI::Range(0.1, 60.0));
  cmd->add_option(
         "--body-motion", a.body_motion,
         "Scale of the body's pitch, roll and bounce (default: the scene's own, 1 outdoors "
         "and 0.3 indoors; 0: a rigid platform on smooth ground)")
      ->check(CLI::Range(0.0, 10.0));
  cmd->add_option("--mount", a.mount,
                  "ROLL PITCH YAW: how the sensor sits on the vehicle, degrees (applied yaw, "
                  "then pitch, then roll, in the vehicle frame: x forward, z up; e.g. 0 10 0 "
                  "tilts it 10 deg nose down, 90 0 0 lays it on its side); the ground truth is "
                  "the sensor's pose (default: level, x forward)")
      ->expected(3);
  cmd->add_option("--height", a.height,
                  "Sensor height above the ground, m (default: the scene's own, 1.9 outdoors "
                  "and 0.5 in the corridor)")
      ->check(CLI::Range(0.2, 2.7));
  cmd->add_flag("--dual", a.dual, "Dual-return mode (last and strongest)");
  cmd->add_option("--rpm", a.rpm, "Rotation speed, 300..1200 in steps of 60 (VLP-16 manual)")
      ->capture_default_str();
  cmd->add_option("--noise", a.noise_m, "Range noise, metres (1 sigma)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1.0));
  cmd->add_option("--start-time", a.start_time_s,
                  "Sensor time of the first packet, Unix seconds (the sensor clock counts "
                  "microseconds past the hour; start just before an hour to test rollover)")
      ->capture_default_str();
}

int run_sim(const SimArgs& a) {
  const auto kind = sim::parse_scene(a.scene);
  if (!kind) {
    spdlog::error("--scene: '{}' is not one of street, campus, corridor, loop", a.scene);
    return core::kExitUsage;
  }
  if (a.rpm < 300 || a.rpm > 1200 || a.rpm % 60 != 0) {
    spdlog::error("--rpm: {} is not 300..1200 in steps of 60", a.rpm);
    return core::kExitUsage;
  }
  if (!(a.start_time_s >= 0 && a.start_time_s < 4e9)) {
    spdlog::error("--start-time: {} is not a Unix time in seconds", a.start_time_s);
    return core::kExitUsage;
  }
  if (!a.outage.empty() && !(a.outage.size() == 2 && a.outage[0] >= 0 && a.outage[1] > 0)) {
    spdlog::error("--outage: expected START SECONDS with START >= 0 and SECONDS > 0");
    return core::kExitUsage;
  }
  if (!a.clock_step.empty() &&
      !(a.clock_step.size() == 2 && a.clock_step[0] >= 0 && a.clock_step[1] != 0 &&
        a.start_time_s + a.clock_step[0] + a.clock_step[1] >= 0)) {
    spdlog::error(
        "--clock-step: expected AT SECONDS with AT >= 0, SECONDS not 0 and the clock staying "
        "after 1970");
    return core::kExitUsage;
  }
  if (a.mount.size() == 3 && !std::all_of(a.mount.begin(), a.mount.end(), [](double d) {
        return std::isfinite(d) && std::abs(d) <= 360.0;
      })) {
    spdlog::error("--mount: expected ROLL PITCH YAW in degrees, each within -360..360");
    return core::kExitUsage;
  }
  if (!a.stop.empty() && !(a.stop.size() == 2 && a.stop[0] >= 0 && a.stop[1] > 0)) {
    spdlog::error("--stop: expected AT SECONDS with AT >= 0 and SECONDS > 0");
    return core::kExitUsage;
  }
  const auto t0 = std::chrono::steady_clock::now();
  sim::Scene scene = sim::build_scene(*kind, a.duration_s, a.movers, a.seed, a.world_seed, a.speed);
  if (a.body_motion >= 0.0) scene.motion_scale = a.body_motion;
  if (a.height > 0.0) scene.sensor_height = a.height;
  if (a.mount.size() == 3) {
    constexpr double kDeg = 3.14159265358979323846 / 180.0;
    scene.mount =
        output::from_roll_pitch_yaw(a.mount[0] * kDeg, a.mount[1] * kDeg, a.mount[2] * kDeg);
  }
  if (a.stop.size() == 2) {
    scene.stop_at_s = a.stop[0];
    scene.stop_s = a.stop[1];
  }
  scene.start_still_s = a.start_still_s;
  sim::LidarSimOptions o;
  o.rpm = a.rpm;
  o.dual = a.dual;
  o.noise_m = a.noise_m;
  o.drop_rate = a.drop_rate;
  if (a.outage.size() == 2) {
    o.outage_start_s = a.outage[0];
    o.outage_s = a.outage[1];
  }
  if (a.clock_step.size() == 2) {
    o.clock_step_at_s = a.clock_step[0];
    o.clock_step_s = a.clock_step[1];
  }
  o.duration_s = a.duration_s;
  o.seed = a.seed;
  o.start_time_ns = static_cast<std::int64_t>(std::llround(a.start_time_s * 1e9));
  auto result = sim::write_simulation(scene, o, a.out_dir);
  if (!result) return fail(result.error());
  const auto& s = result.value();
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  spdlog::info(
      "{} scene, {:.1f} s, seed {}: {} objects, {} movers; {} data packets ({} dropped), "
      "{} position packets, {} scans in {}/capture.pcap and groundtruth.tum ({:.1f} s)",
      a.scene, a.duration_s, a.seed, s.objects, a.movers, s.packets - s.dropped, s.dropped,
      s.position_packets, s.scans, a.out_dir, wall);
  return core::kExitOk;
}

}  // namespace cndt::cli
