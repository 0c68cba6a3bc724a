// The configuration of cndtd and `cndt replay --config`: one TOML file, every key declared once
// in a table (config.cpp) with its type, default, unit, range and documentation. The loader
// reports every unknown key, wrong type and out-of-range value with its line, not just the
// first; config/cndtd.toml is generated from the same table (`cndtd --print-config`).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "cndt/core/result.hpp"

namespace cndt::config {

struct Config {
  struct Sensor {
    std::string source = "udp";  ///< udp | pcap
    std::string pcap;            ///< capture file when source = pcap
    bool pcap_realtime = true;   ///< pace a capture at its recorded rate
    std::string bind_address = "0.0.0.0";
    std::int64_t data_port = 2368;
    std::int64_t position_port = 8308;
    std::string sensor_ip;  ///< accept packets only from this address ("" = any)
    std::int64_t receive_buffer_bytes = 8 << 20;
    std::int64_t packet_queue = 4096;
    std::string model = "auto";
    double cut_angle_deg = 0.0;
    bool cut_at_fov_gap = true;  ///< move the cut into a sector silent every turn
    double min_range_m = 0.4;
    double max_range_m = 130.0;
    bool vertical_offsets = true;
    std::int64_t max_points = 150'000;
  } sensor;
  struct Odometry {
    std::string mode = "consensus";       ///< consensus | naive
    std::string reference = "local-map";  ///< local-map | previous-scan
    double voxel_size_m = 0.5;
    double eta = 0.7;
    double fine_reach_m = 0.125;
    bool pyramid_while_near = false;
    double near_shortfall_fraction = 0.2;
    double near_shortfall_m = 0.02;
    double scan_cell_m = 0.25;
    double map_cell_m = 0.1;
    double min_range_m = 1.0;
    double max_range_m = 100.0;
    bool deskew = true;
    bool level_frame = true;
    std::int64_t deskew_refinements = 2;
    std::int64_t local_map_scans = 60;
    std::int64_t local_map_points = 1'500'000;
    double map_min_translation_m = 1.0;
    double map_admit_distance_m = 0.5;
    std::int64_t max_map_voxels = 400'000;
    std::int64_t min_points = 200;
    double max_acceleration_mps2 = 10.0;
    double max_angular_acceleration_degps2 = 300.0;
    bool bound_degenerate_slide = true;
    double max_speed_mps = 40.0;
    double start_search_radius_m = 2.0;
    double gap_acceleration_mps2 = 2.0;
    double gap_search_radius_m = 10.0;
    double gap_turn_hypothesis_deg = 3.0;
    double prior_weight = 0.003;
    double prior_acceleration_threshold_mps2 = 2.0;
    bool surface_patches = true;
    std::int64_t patches_after_scans = 4;
    double patch_max_tilt_deg = 25.0;
    std::int64_t patches_clean_scans = 3;
    bool deskew_to_mid_scan = false;
    std::int64_t mid_scan_after_clean = 10;
    bool deskew_acceleration = true;
    std::int64_t guess_jitter_seed = 0;
  } odometry;
  struct Mapper {
    bool enabled = false;
    double keyframe_similarity = 0.5;
    std::int64_t keyframe_scans = 10;
    std::int64_t capacity_voxels = 2'000'000;
    double window_m = 0.0;
    double correction_time_constant_s = 0.5;
    std::string load;             ///< prior map to localize in ("" = build one)
    std::string mode = "frozen";  ///< frozen | update (with load)
    std::vector<double> initial_pose{0, 0, 0, 0, 0, 0};  ///< x,y,z m; roll,pitch,yaw deg
    std::string save;  ///< save the map here at exit ("" = do not)
  } mapper;
  struct Runtime {
    std::int64_t scan_ring = 4;
    std::int64_t keyframe_ring = 64;
    std::int64_t keyframe_ring_points = 1'500'000;
    bool realtime = false;
    std::int64_t odometry_priority = 50;
    std::int64_t odometry_cpu = -1;
    std::int64_t mapper_nice = 10;
    std::int64_t mapper_cpu = -1;
    std::int64_t scoring_threads = 2;
    double status_interval_s = 10.0;
  } runtime;
  struct Output {
    double degraded_below_cm = 0.15;
  } output;
  struct Can {
    std::string interface;  ///< SocketCAN interface ("" = none)
    std::string log;        ///< candump log file ("" = none)
    std::string log_interface = "can0";
    std::int64_t base_id = 0x300;
    bool extended = false;
  } can;
  struct Udp {
    std::vector<std::string> destinations;  ///< "ADDRESS:PORT"
  } udp;
  struct Log {
    std::string level = "info";
  } log;
};

/// Reads and checks a config file. Every problem is one line "FILE:LINE:COLUMN: key: what" in
/// the error's message (exit code 78; 66 when the file cannot be read).
core::Result<Config> load_config(const std::string& path);
/// The same from text (tests); `source` names it in messages.
core::Result<Config> parse_config(const std::string& text, const std::string& source);

/// Every key with its documentation, unit, range and default, as a TOML file that loads to the
/// defaults (config/cndtd.toml is this text).
std::string documented_defaults();
/// The effective values of every key, one "section.key = value" per line (for the start-up log).
std::string effective(const Config& config);

}  // namespace cndt::config
