#include "cndt/config/config.hpp"

#include <fmt/format.h>
#include <toml++/toml.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <sstream>
#include <string_view>
#include <variant>

namespace cndt::config {
namespace {

template <class T>
using Ref = T& (*)(Config&);
using AnyRef = std::variant<Ref<bool>, Ref<std::int64_t>, Ref<double>, Ref<std::string>,
                            Ref<std::vector<double>>, Ref<std::vector<std::string>>>;

constexpr double kInf = std::numeric_limits<double>::infinity();

struct Field {
  std::string_view section;
  std::string_view key;
  AnyRef ref;
  std::string_view doc;
  std::string_view unit = {};
  double min = -kInf, max = kInf;              ///< numbers (each element of a number array)
  std::vector<std::string_view> choices = {};  ///< strings
  std::size_t size = 0;                        ///< arrays: exact element count (0: any)
};

struct Section {
  std::string_view name;
  std::string_view doc;
};

#define CNDT_REF(member)     \
  +[](Config & c) -> auto& { \
    return c.member;         \
  }

const std::vector<Section>& sections() {
  static const std::vector<Section> s{
      {"sensor", "Where VLP-16 packets come from and how they become scans."},
      {"odometry",
       "Consensus-NDT odometry (the paper's section 3.1), on the highest-priority "
       "thread."},
      {"mapper", "Keyframes, the eq-7 joint refinement and the map, on a low-priority thread."},
      {"runtime", "Threads, rings and real-time setup."},
      {"output", "What is published for every pose."},
      {"can", "CAN output: five frames per pose as config/cndt.dbc describes."},
      {"udp", "UDP output: one datagram per pose as docs/protocol.md describes."},
      {"log", "Logging."},
  };
  return s;
}

const std::vector<Field>& fields() {
  static const std::vector<Field> f{
      {"sensor",
       "source",
       CNDT_REF(sensor.source),
       "Where packets come from: udp (a live sensor) or pcap (a capture file, for tests and "
       "demonstrations).",
       "",
       -kInf,
       kInf,
       {"udp", "pcap"}},
      {"sensor", "pcap", CNDT_REF(sensor.pcap), "Capture file read when source = \"pcap\"."},
      {"sensor", "pcap_realtime", CNDT_REF(sensor.pcap_realtime),
       "With source = \"pcap\": deliver packets at their recorded pace (true) or as fast as the "
       "odometry takes them (false)."},
      {"sensor", "bind_address", CNDT_REF(sensor.bind_address),
       "Local address the UDP sockets bind to."},
      {"sensor", "data_port", CNDT_REF(sensor.data_port), "UDP port of data packets.", "", 1,
       65535},
      {"sensor", "position_port", CNDT_REF(sensor.position_port),
       "UDP port of position (GPS/PPS) packets; 0 = do not listen.", "", 0, 65535},
      {"sensor", "sensor_ip", CNDT_REF(sensor.sensor_ip),
       "Accept packets only from this address (\"\" = from any)."},
      {"sensor", "receive_buffer_bytes", CNDT_REF(sensor.receive_buffer_bytes),
       "SO_RCVBUF asked for (the kernel caps it at net.core.rmem_max).", "bytes", 65536, 1 << 30},
      {"sensor", "packet_queue", CNDT_REF(sensor.packet_queue),
       "Packets buffered between the receiver thread and the driver.", "packets", 64, 1 << 20},
      {"sensor",
       "model",
       CNDT_REF(sensor.model),
       "Sensor model; auto reads the product byte of the packets.",
       "",
       -kInf,
       kInf,
       {"auto", "vlp16", "vlp16-hires", "hdl32e", "vlp32c"}},
      {"sensor", "cut_angle_deg", CNDT_REF(sensor.cut_angle_deg),
       "Azimuth where one revolution ends and the next begins.", "deg", 0, 359.99},
      {"sensor", "cut_at_fov_gap", CNDT_REF(sensor.cut_at_fov_gap),
       "When the sensor is silent over the same sector every turn (a limited field of view), "
       "cut the revolutions inside that sector (at cut_angle_deg if it lies there, else in the "
       "middle), and do not count the silence as packet loss."},
      {"sensor", "min_range_m", CNDT_REF(sensor.min_range_m), "Drop returns nearer than this.", "m",
       0, 1000},
      {"sensor", "max_range_m", CNDT_REF(sensor.max_range_m), "Drop returns farther than this.",
       "m", 0.1, 1000},
      {"sensor", "vertical_offsets", CNDT_REF(sensor.vertical_offsets),
       "Add the per-laser vertical offsets of the VLP-16 manual."},
      {"sensor", "max_points", CNDT_REF(sensor.max_points),
       "Point capacity of one scan (allocated once).", "points", 1000, 10'000'000},

      {"odometry",
       "mode",
       CNDT_REF(odometry.mode),
       "consensus: coarse match, Cv cut at eta, fine match; naive: one match over all voxels.",
       "",
       -kInf,
       kInf,
       {"consensus", "naive"}},
      {"odometry",
       "reference",
       CNDT_REF(odometry.reference),
       "What each scan is matched against: local-map (recent scans merged) or previous-scan "
       "(the paper's choice).",
       "",
       -kInf,
       kInf,
       {"local-map", "previous-scan"}},
      {"odometry", "voxel_size_m", CNDT_REF(odometry.voxel_size_m),
       "NDT voxel size L (paper: 0.5).", "m", 0.05, 10},
      {"odometry", "eta", CNDT_REF(odometry.eta),
       "Voxel consensus threshold: voxels with Cv below it are dropped before the fine match "
       "(paper: 0.7).",
       "", 0, 1},
      {"odometry", "fine_reach_m", CNDT_REF(odometry.fine_reach_m),
       "How far the fine match may move the pose from the coarse one (a turn counted by how far "
       "it moves a point at the scan's RMS range). Cv judged the voxels where the coarse pose put "
       "the points; a fine match going farther is matched again with every voxel (flag 128). "
       "0 = no limit (the paper).",
       "m", 0, 10},
      {"odometry", "pyramid_while_near", CNDT_REF(odometry.pyramid_while_near),
       "While every scan in the local map lies within map_admit_distance_m of the vehicle (the "
       "start, until it has moved that far from its first scan), match on the 1 m pyramid grid "
       "alone (flag 256): the fine grid of a scan taken that near pulls towards zero motion, "
       "its ring arcs lying where the new scan has its own. Helps platforms that start slowly "
       "or from rest and sensors at 900-1200 rpm (under 0.5 m per revolution). Off by default: "
       "alone it costs the consensus mode on a 600 rpm campus drive; with surface_patches on "
       "every plane (patch_max_tilt_deg = 90, patches_after_scans = 4) it does not "
       "(docs/odometry.md)."},
      {"odometry", "near_shortfall_fraction", CNDT_REF(odometry.near_shortfall_fraction),
       "While every scan in the local map lies within map_admit_distance_m of the pyramid's "
       "pose (as for pyramid_while_near): when the coarse and fine matches move the sensor "
       "less far than the pyramid did, short by more than this fraction of the pyramid's "
       "motion (and at least near_shortfall_m), the fine grid's ring arcs have pulled the match "
       "back towards the reference scans, and the pyramid's pose is taken (flags 256 and 512, "
       "published as degraded) unless the fine grid finds the scene degenerate. Saves starts "
       "at speed; where the two agree the fine match stands. 0 = no check.",
       "", 0, 1},
      {"odometry", "near_shortfall_m", CNDT_REF(odometry.near_shortfall_m),
       "The least shortfall near_shortfall_fraction acts on (the pyramid's pose is good to a "
       "few centimetres).",
       "m", 0, 10},
      {"odometry", "scan_cell_m", CNDT_REF(odometry.scan_cell_m),
       "Downsampling of the scan being matched: the cell centroids are the points matched. "
       "Cells as large as the voxels make the score ripple along every plane (the centroids of "
       "an evenly sampled surface line up with the voxel means once per cell of motion; "
       "docs/odometry.md).",
       "m", 0.01, 10},
      {"odometry", "map_cell_m", CNDT_REF(odometry.map_cell_m),
       "Downsampling of scans added to the reference and used for Cv.", "m", 0.01, 10},
      {"odometry", "min_range_m", CNDT_REF(odometry.min_range_m),
       "Points nearer than this are the vehicle itself and are not matched.", "m", 0, 1000},
      {"odometry", "max_range_m", CNDT_REF(odometry.max_range_m),
       "Points farther than this are not matched.", "m", 0.1, 1000},
      {"odometry", "deskew", CNDT_REF(odometry.deskew),
       "Undistort each scan with the estimated motion (every point has its firing time)."},
      {"odometry", "level_frame", CNDT_REF(odometry.level_frame),
       "A sensor mounted more than 5 deg off level (pitched down to see the ground, say) is "
       "matched turned level: the first scan's ground gives the up direction. Poses are still "
       "the sensor's, in its first scan's frame (docs/odometry.md)."},
      {"odometry", "deskew_refinements", CNDT_REF(odometry.deskew_refinements),
       "The matches solve for the scan's motion with its pose; when a match ends more than "
       "0.1 m or 0.01 rad from the pose the scan was deskewed for, it is deskewed again and "
       "matched again, at most this many times.",
       "", 0, 5},
      {"odometry", "local_map_scans", CNDT_REF(odometry.local_map_scans),
       "Scans the local-map reference holds.", "scans", 1, 1000},
      {"odometry", "local_map_points", CNDT_REF(odometry.local_map_points),
       "Points the local-map scans hold together (one buffer, allocated once, at least "
       "max_points); when a new scan does not fit, the oldest scans leave until it does.",
       "points", 1000, 100'000'000},
      {"odometry", "map_min_translation_m", CNDT_REF(odometry.map_min_translation_m),
       "A scan enters the local map once the sensor has moved this far (or turned 2 deg) since "
       "the last one that did, so the map spans local_map_scans times this distance. 2 m was "
       "measured level or better on typical drives and 1.5 ms a scan cheaper at 8 m/s, but it "
       "lost steeply tilted mounts and noisy slow spins (docs/odometry.md).",
       "m", 0, 100},
      {"odometry", "map_admit_distance_m", CNDT_REF(odometry.map_admit_distance_m),
       "A scan taken into the local map is matched against only once the predicted pose is this "
       "far from where it was taken (or turned 2 deg from it): near its own pose a scan's ring "
       "pattern pulls the next scans' matches towards zero motion, which holds a slow vehicle "
       "(0 = at once; docs/odometry.md).",
       "m", 0, 100},
      {"odometry", "max_map_voxels", CNDT_REF(odometry.max_map_voxels),
       "Voxel capacity of the reference NDT (allocated once).", "voxels", 1000, 50'000'000},
      {"odometry", "min_points", CNDT_REF(odometry.min_points),
       "A scan with fewer points after downsampling is not matched (the pose is predicted and "
       "published as lost).",
       "points", 10, 1'000'000},
      {"odometry", "max_acceleration_mps2", CNDT_REF(odometry.max_acceleration_mps2),
       "Largest acceleration of the vehicle. A match farther from the constant-velocity "
       "prediction than this allows over one time step (0.1 m at 10 m/s^2 and 10 Hz) is taken "
       "for a wrong minimum and matched again from the prediction: a young reference can hold a "
       "scan near zero motion (0 = never; docs/odometry.md).",
       "m/s^2", 0, 1000},
      {"odometry", "max_angular_acceleration_degps2",
       CNDT_REF(odometry.max_angular_acceleration_degps2),
       "Largest angular acceleration of the vehicle about the sensor's axis. A match whose turn "
       "about the axis is farther from the constant-velocity prediction's than this allows over "
       "one time step (3 deg at 300 deg/s^2 and 10 Hz, at least 1.5 deg) is matched again from "
       "the prediction, as for max_acceleration_mps2: pulling away among pedestrians a match can "
       "turn by degrees in one scan, as the rings turned about the axis lie on themselves "
       "(0 = never; docs/odometry.md, \"Turn check\").",
       "deg/s^2", 0, 100000},
      {"odometry", "bound_degenerate_slide", CNDT_REF(odometry.bound_degenerate_slide),
       "A degenerate match (the scene leaves the position free along some direction) is moved "
       "along that direction back to within the distance max_acceleration_mps2 allows from the "
       "constant-velocity prediction: what it did there was the solver's slide, not the vehicle's "
       "motion. Only once three matches in a row were clean, so that the prediction was measured "
       "(docs/odometry.md, \"Degenerate slide\")."},
      {"odometry", "max_speed_mps", CNDT_REF(odometry.max_speed_mps),
       "Top speed of the vehicle. The first match has no velocity to start from: horizontal "
       "offsets up to 2 m are scored, and while the best lies on the edge of those scored the "
       "search grows, up to the distance this speed covers between the first two scans (4 m at "
       "40 m/s and 10 Hz, at most 10 m; 0 = no growing; docs/odometry.md).",
       "m/s", 0, 100},
      {"odometry", "start_search_radius_m", CNDT_REF(odometry.start_search_radius_m),
       "Before the first match, and after a gap in the data, horizontal offsets this far from "
       "the start (the prediction after a gap) are scored on the coarsest grid, in 0.5 m steps, "
       "and the best one starts the match (docs/odometry.md, \"Starting at speed\", \"Gaps in "
       "the data\").",
       "m", 0, 10},
      {"odometry", "gap_acceleration_mps2", CNDT_REF(odometry.gap_acceleration_mps2),
       "After a gap in the data the vehicle may have sped up or slowed down: the search looks "
       "along the predicted motion up to start_search_radius_m plus this acceleration's "
       "dt^2 / 2 from the prediction (dt the time since the last scan; 3 s: 9 m more at "
       "2 m/s^2), across it start_search_radius_m (docs/odometry.md, \"Gaps in the data\").",
       "m/s^2", 0, 100},
      {"odometry", "gap_search_radius_m", CNDT_REF(odometry.gap_search_radius_m),
       "The farthest those searches reach: along the motion after a gap, and the first match's "
       "growing search (max_speed_mps).",
       "m", 0, 100},
      {"odometry", "gap_turn_hypothesis_deg", CNDT_REF(odometry.gap_turn_hypothesis_deg),
       "After a gap over which the prediction turns by more than this (the last scan's turn "
       "rate times the gap), starts with that turn halved and taken out are searched as well: "
       "the vehicle may have ended its turn while nothing arrived (0 = after every gap; "
       "negative = never; docs/odometry.md, \"Gaps in the data\").",
       "deg", -1, 180},
      {"odometry", "prior_weight", CNDT_REF(odometry.prior_weight),
       "Pull of every match towards the constant-velocity prediction's position, relative to "
       "the scene's strongest constraint on the position (the largest eigenvalue of the NDT "
       "Hessian's translation block). Applied after a clean match; along directions the scene "
       "leaves nearly free (a bare street or corridor) the prediction decides instead of noise "
       "(0 = off; docs/odometry.md).",
       "", 0, 1},
      {"odometry", "prior_acceleration_threshold_mps2",
       CNDT_REF(odometry.prior_acceleration_threshold_mps2),
       "While the speed changes faster than this the same way at two scans in a row (braking, "
       "pulling away), the prior's centre moves on by the change of speed: the constant-velocity "
       "prediction is a dt^2 / 2 off such a vehicle, and the pull would hold a weakly held match "
       "there (0 = the centre always at constant velocity; docs/odometry.md, \"Position prior\").",
       "m/s^2", 0, 1000},
      {"odometry", "surface_patches", CNDT_REF(odometry.surface_patches),
       "A reference voxel whose neighbourhood holds a plane is matched as a piece of that plane "
       "(its own spread along the normal, along the plane at least the voxel size squared) "
       "instead of the "
       "ring arcs a scan left in it, which move with the sensor and pull scans to line up their "
       "rings. On by default for level planes only (patch_max_tilt_deg, patches_clean_scans): "
       "the ground's ring arcs otherwise tilt the estimate and lift its height. false = the "
       "paper's voxel Gaussians everywhere (eq 4; docs/odometry.md, \"Level patches\")."},
      {"odometry", "patches_after_scans", CNDT_REF(odometry.patches_after_scans),
       "Surface patches only once the local map holds this many scans: a plane judged from "
       "one or two sparse scans (900-1200 rpm) may be a few unrelated ring arcs; a campus drive "
       "at 1200 rpm was lost at its sixth scan with patches once the map held two "
       "(docs/odometry.md, \"Level patches\").",
       "scans", 0, 1000},
      {"odometry", "patch_max_tilt_deg", CNDT_REF(odometry.patch_max_tilt_deg),
       "With surface_patches, patches only for planes whose normal is within this angle of the "
       "odometry frame's z (the first scan's): 25 keeps them to the ground and other level "
       "surfaces, whose ring arcs tilt the start and lift the height, while walls and movers' "
       "sides keep the paper's Gaussians; 90 = every plane (docs/odometry.md, \"Level "
       "patches\").",
       "deg", 0, 90},
      {"odometry", "patches_clean_scans", CNDT_REF(odometry.patches_clean_scans),
       "Surface patches only after this many matches in a row not flagged degenerate (at the "
       "start of a drive too, whose first matches are on the paper's Gaussians); a match "
       "degenerate with patches is matched again without them (flag 1024) and they stay off "
       "until then: where the rest of the scene leaves the position free, the texture the rings "
       "give the ground is what holds it. This count and patches_after_scans are checked when "
       "the local map takes a scan (0 = patches regardless; docs/odometry.md, \"Level "
       "patches\").",
       "scans", 0, 100000},
      {"odometry", "deskew_to_mid_scan", CNDT_REF(odometry.deskew_to_mid_scan),
       "Deskew to the sensor pose at mid-revolution instead of the scan stamp, once "
       "mid_scan_after_clean clean matches have measured the velocity (the reported pose stays "
       "at the stamp; deskew_acceleration does not apply). Lowers RTE on most simulated drives "
       "(a body pitching within a revolution is not smoothed over three scans), but some lose "
       "more than the rest gain (docs/odometry.md, \"Deskew to mid-revolution\")."},
      {"odometry", "mid_scan_after_clean", CNDT_REF(odometry.mid_scan_after_clean),
       "With deskew_to_mid_scan: deskew to the stamp until this many clean matches in a row "
       "(none across a gap) have measured the velocity, then to mid-revolution (0 = from the "
       "first scan, where the start-up matches went 0.1-0.4 m off on drives the stamp deskew "
       "starts cleanly).",
       "matches", 0, 100000},
      {"odometry", "deskew_acceleration", CNDT_REF(odometry.deskew_acceleration),
       "Deskew with the velocity at the scan stamp from the last three poses (after a clean "
       "match) instead of the mean velocity over the last period, which lags half a period "
       "behind: follows a vehicle pitching on its suspension, most at 300-420 rpm "
       "(docs/odometry.md, \"Deskew velocity\"). Not with deskew_to_mid_scan, where it lost "
       "drives with the sensor turned in yaw."},
      {"odometry", "guess_jitter_seed", CNDT_REF(odometry.guess_jitter_seed),
       "For evaluation only (0 = off): every match starts from its initial guess moved by at most "
       "0.5e-9 m / rad per coordinate, drawn from this seed, to show how far results depend on "
       "chance at the level of rounding (docs/accuracy.md).",
       "", 0, 1'000'000'000},

      {"mapper", "enabled", CNDT_REF(mapper.enabled),
       "Run the mapper thread: keyframes, eq-7 refinement, a map and the correction T_map_odom "
       "applied to published poses. Off by default (it takes a second core); on 120 s simulated "
       "loop and street drives it brings the ATE to 0.1-0.3 x the odometry's (docs/mapper.md)."},
      {"mapper", "keyframe_similarity", CNDT_REF(mapper.keyframe_similarity),
       "A keyframe closes when the current scan's voxel overlap with its first scan falls below "
       "this.",
       "", 0, 1},
      {"mapper", "keyframe_scans", CNDT_REF(mapper.keyframe_scans),
       "Most scans one keyframe holds.", "scans", 2, 100},
      {"mapper", "capacity_voxels", CNDT_REF(mapper.capacity_voxels),
       "Map capacity (about 250 bytes each).", "voxels", 1000, 100'000'000},
      {"mapper", "window_m", CNDT_REF(mapper.window_m),
       "Keep only map voxels within this horizontal distance of the vehicle (0 = keep all; "
       "memory then grows with the area driven).",
       "m", 0, 1e5},
      {"mapper", "correction_time_constant_s", CNDT_REF(mapper.correction_time_constant_s),
       "Published poses follow each new map correction with this time constant instead of "
       "jumping to it (0 = at once). On 120 s simulated loop and street drives 0.5 s brings the "
       "published poses' frame-to-frame error from 10-15 % above the odometry's to 1-2 % above, "
       "the ATE unchanged (docs/mapper.md).",
       "s", 0, 60},
      {"mapper", "load", CNDT_REF(mapper.load),
       "Prior map file to localize in (\"\" = build a map from scratch)."},
      {"mapper",
       "mode",
       CNDT_REF(mapper.mode),
       "With load: frozen (the prior map is not changed) or update (refined scans are added).",
       "",
       -kInf,
       kInf,
       {"frozen", "update"}},
      {"mapper",
       "initial_pose",
       CNDT_REF(mapper.initial_pose),
       "With load: the first scan's pose in the map frame, [x, y, z, roll, pitch, yaw] (m, "
       "deg).",
       "",
       -1e7,
       1e7,
       {},
       6},
      {"mapper", "save", CNDT_REF(mapper.save),
       "Save the map here (atomically) when the daemon stops (\"\" = do not save)."},

      {"runtime", "scan_ring", CNDT_REF(runtime.scan_ring),
       "Scans buffered between the driver and the odometry. Live input: when full the oldest "
       "scan is dropped and counted; replay waits instead.",
       "scans", 2, 64},
      {"runtime", "keyframe_ring", CNDT_REF(runtime.keyframe_ring),
       "Scans buffered between the odometry and the mapper (in a replay also how many scans the "
       "odometry may run ahead of the mapper).",
       "scans", 2, 1024},
      {"runtime", "keyframe_ring_points", CNDT_REF(runtime.keyframe_ring_points),
       "Points the scans buffered for the mapper hold together (one buffer, allocated once, at "
       "least max_points). Live input: a scan that does not fit is not mapped (counted); replay "
       "waits instead.",
       "points", 1000, 100'000'000},
      {"runtime", "realtime", CNDT_REF(runtime.realtime),
       "Lock memory (mlockall) and run the odometry thread SCHED_FIFO; without the privilege "
       "one warning is logged and the daemon runs on."},
      {"runtime", "odometry_priority", CNDT_REF(runtime.odometry_priority),
       "SCHED_FIFO priority of the odometry thread with realtime = true.", "", 1, 98},
      {"runtime", "odometry_cpu", CNDT_REF(runtime.odometry_cpu),
       "CPU the odometry thread is pinned to (-1 = any).", "", -1, 1023},
      {"runtime", "mapper_nice", CNDT_REF(runtime.mapper_nice),
       "Nice value of the mapper thread (higher = lower priority).", "", 0, 19},
      {"runtime", "mapper_cpu", CNDT_REF(runtime.mapper_cpu),
       "CPU the mapper thread is pinned to (-1 = any).", "", -1, 1023},
      {"runtime", "scoring_threads", CNDT_REF(runtime.scoring_threads),
       "Threads that score each scan against the reference: the odometry thread and "
       "scoring_threads - 1 helpers (SCHED_FIFO like the odometry thread with realtime = true, "
       "not pinned). Lowers the latency on a multi-core computer; the poses are the same for "
       "every value.",
       "threads", 1, 16},
      {"runtime", "status_interval_s", CNDT_REF(runtime.status_interval_s),
       "Seconds between health lines in the log (and STATUS= updates for systemd).", "s", 0.5,
       3600},

      {"output", "degraded_below_cm", CNDT_REF(output.degraded_below_cm),
       "A matched pose with Cm below this is published as degraded.", "", 0, 1},

      {"can", "interface", CNDT_REF(can.interface),
       "SocketCAN interface to send on, e.g. can0 or vcan0 (\"\" = none)."},
      {"can", "log", CNDT_REF(can.log),
       "Also write every frame to this candump log file (\"\" = none)."},
      {"can", "log_interface", CNDT_REF(can.log_interface),
       "Interface name written in the candump log."},
      {"can", "base_id", CNDT_REF(can.base_id),
       "Id of the first of the five pose frames (0x300 = 768; config/cndt.dbc describes the "
       "default).",
       "", 0, 0x1FFFFFFB},
      {"can", "extended", CNDT_REF(can.extended), "Send 29-bit extended ids."},

      {"udp", "destinations", CNDT_REF(udp.destinations),
       "Send each pose datagram to these \"ADDRESS:PORT\" endpoints."},

      {"log",
       "level",
       CNDT_REF(log.level),
       "Log level.",
       "",
       -kInf,
       kInf,
       {"trace", "debug", "info", "warn", "error"}},
  };
  return f;
}

#undef CNDT_REF

const Field* find_field(std::string_view section, std::string_view key) {
  for (const auto& f : fields()) {
    if (f.section == section && f.key == key) return &f;
  }
  return nullptr;
}

std::size_t edit_distance(std::string_view a, std::string_view b) {
  std::vector<std::size_t> prev(b.size() + 1), cur(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) prev[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    cur[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      cur[j] =
          std::min({prev[j] + 1, cur[j - 1] + 1, prev[j - 1] + (a[i - 1] == b[j - 1] ? 0u : 1u)});
    }
    std::swap(prev, cur);
  }
  return prev[b.size()];
}

std::string suggestion(std::string_view section, std::string_view key) {
  std::string best;
  std::size_t best_d = 3;  // only close misspellings
  for (const auto& f : fields()) {
    if (f.section != section) continue;
    const std::size_t d = edit_distance(key, f.key);
    if (d < best_d) {
      best_d = d;
      best = fmt::format(" (did you mean '{}'?)", f.key);
    }
  }
  return best;
}

std::string type_name(const toml::node& n) {
  switch (n.type()) {
    case toml::node_type::string:
      return "a string";
    case toml::node_type::integer:
      return "an integer";
    case toml::node_type::floating_point:
      return "a number";
    case toml::node_type::boolean:
      return "a boolean";
    case toml::node_type::array:
      return "an array";
    case toml::node_type::table:
      return "a table";
    default:
      return "a date/time";
  }
}

std::string format_number(double v) {
  if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
  std::string s = fmt::format("{}", v);
  return s;
}

std::string range_text(const Field& f) {
  return fmt::format("[{}, {}]", format_number(f.min), format_number(f.max));
}

std::string quote(const std::string& s) {
  std::string out = "\"";
  for (const char c : s) {
    if (c == '"' || c == '\\') out += '\\';
    out += c;
  }
  return out + "\"";
}

std::string value_text(Config& c, const Field& f) {
  return std::visit(
      [&](auto ref) -> std::string {
        const auto& v = ref(c);
        using T = std::decay_t<decltype(v)>;
        if constexpr (std::is_same_v<T, bool>) {
          return v ? "true" : "false";
        } else if constexpr (std::is_same_v<T, std::int64_t>) {
          return fmt::format("{}", v);
        } else if constexpr (std::is_same_v<T, double>) {
          std::string s = fmt::format("{}", v);
          if (s.find_first_of(".eE") == std::string::npos) s += ".0";
          return s;
        } else if constexpr (std::is_same_v<T, std::string>) {
          return quote(v);
        } else if constexpr (std::is_same_v<T, std::vector<double>>) {
          std::string s = "[";
          for (std::size_t i = 0; i < v.size(); ++i) {
            s += (i ? ", " : "") + fmt::format("{}", v[i]);
          }
          return s + "]";
        } else {
          std::string s = "[";
          for (std::size_t i = 0; i < v.size(); ++i) s += (i ? ", " : "") + quote(v[i]);
          return s + "]";
        }
      },
      f.ref);
}

class Checker {
 public:
  Checker(std::string source, Config& config) : source_(std::move(source)), c_(config) {}

  void error(const toml::source_region& where, std::string_view key, const std::string& what) {
    if (where.begin.line > 0) {
      errors_.push_back(fmt::format("{}:{}:{}: {}: {}", source_, where.begin.line,
                                    where.begin.column, key, what));
    } else {
      errors_.push_back(fmt::format("{}: {}: {}", source_, key, what));
    }
  }

  void check_number(const toml::node& n, const Field& f, const std::string& key, double v) {
    if (!std::isfinite(v) || v < f.min || v > f.max) {
      error(n.source(), key,
            fmt::format("{} is out of range {}{}", format_number(v), range_text(f),
                        f.unit.empty() ? "" : fmt::format(" ({})", f.unit)));
    }
  }

  void set(const toml::node& n, const Field& f) {
    const std::string key = fmt::format("{}.{}", f.section, f.key);
    std::visit(
        [&](auto ref) {
          auto& v = ref(c_);
          using T = std::decay_t<decltype(v)>;
          if constexpr (std::is_same_v<T, bool>) {
            if (!n.is_boolean()) return wrong(n, key, "a boolean (true or false)");
            v = n.as_boolean()->get();
          } else if constexpr (std::is_same_v<T, std::int64_t>) {
            if (!n.is_integer()) return wrong(n, key, "an integer");
            const std::int64_t x = n.as_integer()->get();
            check_number(n, f, key, static_cast<double>(x));
            v = x;
          } else if constexpr (std::is_same_v<T, double>) {
            if (!n.is_number()) return wrong(n, key, "a number");
            const double x = n.is_integer() ? static_cast<double>(n.as_integer()->get())
                                            : n.as_floating_point()->get();
            check_number(n, f, key, x);
            v = x;
          } else if constexpr (std::is_same_v<T, std::string>) {
            if (!n.is_string()) return wrong(n, key, "a string");
            const std::string s = n.as_string()->get();
            if (!f.choices.empty() && std::find(f.choices.begin(), f.choices.end(),
                                                std::string_view(s)) == f.choices.end()) {
              std::string list;
              for (const auto& ch : f.choices) list += (list.empty() ? "" : ", ") + std::string(ch);
              error(n.source(), key, fmt::format("'{}' is not one of {}", s, list));
            }
            v = s;
          } else if constexpr (std::is_same_v<T, std::vector<double>>) {
            if (!n.is_array()) return wrong(n, key, "an array of numbers");
            const auto& a = *n.as_array();
            if (f.size != 0 && a.size() != f.size) {
              return error(n.source(), key,
                           fmt::format("expected {} numbers, got {}", f.size, a.size()));
            }
            std::vector<double> out;
            for (const auto& e : a) {
              if (!e.is_number()) return wrong(e, key, "an array of numbers");
              const double x = e.is_integer() ? static_cast<double>(e.as_integer()->get())
                                              : e.as_floating_point()->get();
              check_number(e, f, key, x);
              out.push_back(x);
            }
            v = out;
          } else {
            if (!n.is_array()) return wrong(n, key, "an array of strings");
            std::vector<std::string> out;
            for (const auto& e : *n.as_array()) {
              if (!e.is_string()) return wrong(e, key, "an array of strings");
              out.push_back(e.as_string()->get());
            }
            v = out;
          }
        },
        f.ref);
  }

  void wrong(const toml::node& n, const std::string& key, std::string_view expected) {
    error(n.source(), key, fmt::format("expected {}, got {}", expected, type_name(n)));
  }

  std::vector<std::string>& errors() { return errors_; }

 private:
  std::string source_;
  Config& c_;
  std::vector<std::string> errors_;
};

}  // namespace

core::Result<Config> parse_config(const std::string& text, const std::string& source) {
  toml::table root;
  try {
    root = toml::parse(text, source);
  } catch (const toml::parse_error& e) {
    return core::Error{core::kExitConfigError,
                       fmt::format("{}:{}:{}: TOML syntax error: {}", source, e.source().begin.line,
                                   e.source().begin.column, e.description())};
  }
  Config config;
  Checker check(source, config);
  std::vector<const toml::node*> where(fields().size(), nullptr);
  for (const auto& [section_key, section_node] : root) {
    const std::string_view section = section_key.str();
    const bool known = std::any_of(sections().begin(), sections().end(),
                                   [&](const Section& s) { return s.name == section; });
    if (!known) {
      std::string names;
      for (const auto& s : sections()) names += (names.empty() ? "" : ", ") + std::string(s.name);
      check.error(section_key.source(), section, fmt::format("unknown section (known: {})", names));
      continue;
    }
    if (!section_node.is_table()) {
      check.error(section_node.source(), section,
                  fmt::format("expected a table [{}], got {}", section, type_name(section_node)));
      continue;
    }
    for (const auto& [key, node] : *section_node.as_table()) {
      const Field* f = find_field(section, key.str());
      if (f == nullptr) {
        check.error(key.source(), fmt::format("{}.{}", section, key.str()),
                    "unknown key" + suggestion(section, key.str()));
        continue;
      }
      where[static_cast<std::size_t>(f - fields().data())] = &node;
      check.set(node, *f);
    }
  }
  // Relations between keys, reported at the later key.
  const auto at = [&](std::string_view section, std::string_view key) {
    const Field* f = find_field(section, key);
    const toml::node* n = where[static_cast<std::size_t>(f - fields().data())];
    return n != nullptr ? n->source() : toml::source_region{};
  };
  if (config.sensor.min_range_m >= config.sensor.max_range_m) {
    check.error(
        at("sensor", "max_range_m"), "sensor.max_range_m",
        fmt::format("must be greater than sensor.min_range_m ({})", config.sensor.min_range_m));
  }
  if (config.odometry.min_range_m >= config.odometry.max_range_m) {
    check.error(
        at("odometry", "max_range_m"), "odometry.max_range_m",
        fmt::format("must be greater than odometry.min_range_m ({})", config.odometry.min_range_m));
  }
  if (config.sensor.source == "pcap" && config.sensor.pcap.empty()) {
    check.error(at("sensor", "source"), "sensor.pcap",
                "source = \"pcap\" needs the capture file in sensor.pcap");
  }
  for (const std::string& d : config.udp.destinations) {
    const auto colon = d.rfind(':');
    if (colon == std::string::npos || colon == 0 || colon + 1 == d.size()) {
      check.error(at("udp", "destinations"), "udp.destinations",
                  fmt::format("'{}' is not ADDRESS:PORT", d));
    }
  }
  if (!check.errors().empty()) {
    std::string all;
    for (const auto& e : check.errors()) all += (all.empty() ? "" : "\n") + e;
    return core::Error{core::kExitConfigError, all};
  }
  return config;
}

core::Result<Config> load_config(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    return core::Error{core::kExitNoInput,
                       fmt::format("cannot read config file '{}': {}", path, std::strerror(errno))};
  }
  std::ostringstream ss;
  ss << in.rdbuf();
  return parse_config(ss.str(), path);
}

std::string documented_defaults() {
  Config c;
  std::string out =
      "# cndtd configuration (also read by `cndt replay --config`).\n"
      "#\n"
      "# Every key is optional: the value shown is the default. Unknown keys, values of the wrong\n"
      "# type and values outside the range given are errors that name the key and the line\n"
      "# (cndtd exits with 78). `cndtd --check --config FILE` checks a file; `cndtd\n"
      "# --print-config` prints this text. Unit, range and choices follow each description.\n";
  for (const auto& s : sections()) {
    out += fmt::format("\n# {}\n[{}]\n", s.doc, s.name);
    for (const auto& f : fields()) {
      if (f.section != s.name) continue;
      out += fmt::format("\n# {}", f.doc);
      std::vector<std::string> notes;
      if (!f.unit.empty()) notes.push_back(fmt::format("unit: {}", f.unit));
      const bool numeric = std::holds_alternative<Ref<std::int64_t>>(f.ref) ||
                           std::holds_alternative<Ref<double>>(f.ref) ||
                           std::holds_alternative<Ref<std::vector<double>>>(f.ref);
      if (numeric && (std::isfinite(f.min) || std::isfinite(f.max))) {
        notes.push_back(fmt::format("range: {}", range_text(f)));
      }
      if (!f.choices.empty()) {
        std::string list;
        for (const auto& ch : f.choices) list += (list.empty() ? "" : " | ") + std::string(ch);
        notes.push_back("one of: " + list);
      }
      if (!notes.empty()) {
        std::string joined;
        for (const auto& n : notes) joined += (joined.empty() ? "" : "; ") + n;
        out += fmt::format(" ({})", joined);
      }
      out += fmt::format("\n{} = {}\n", f.key, value_text(c, f));
    }
  }
  // Wrap the comment lines at 100 columns.
  std::string wrapped;
  std::istringstream in(out);
  for (std::string line; std::getline(in, line);) {
    while (line.size() > 100 && line.rfind("# ", 0) == 0) {
      auto cut = line.rfind(' ', 100);
      if (cut == std::string::npos || cut <= 2) break;
      wrapped += line.substr(0, cut) + "\n";
      line = "# " + line.substr(cut + 1);
    }
    wrapped += line + "\n";
  }
  return wrapped;
}

std::string effective(const Config& config) {
  Config c = config;
  std::string out;
  for (const auto& f : fields()) {
    out += fmt::format("{}.{} = {}\n", f.section, f.key, value_text(c, f));
  }
  return out;
}

}  // namespace cndt::config
