// The `cndt` subcommands. Each registers its options on a CLI11 subcommand and runs from a plain
// argument struct, so tests can call run_* directly. run_* returns a process exit code.
#pragma once

#include <CLI/CLI.hpp>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "cndt/cli/capture.hpp"
#include "cndt/config/config.hpp"

namespace cndt::cli {

/// Logs a setup error as one line and returns its exit code.
int fail(const core::Error& error);
/// Creates an output folder (and its parents); the error names the folder.
std::optional<core::Error> create_output_dir(const std::string& dir);
/// Logs one warning when the capture ended in the middle of a record.
void warn_if_cut_short(const CaptureReport& report);

/// Capture-reading options shared by info, decode and (later) replay.
struct CaptureArgs {
  std::string model = "auto";
  std::string sensor_ip;
  std::uint16_t data_port = 2368;
  std::uint16_t position_port = 8308;
  double cut_angle_deg = 0.0;
  double min_range_m = 0.4;
  double max_range_m = 130.0;
  bool no_vertical_offsets = false;
  bool no_fov_cut = false;
  std::size_t max_points = 150'000;
};
void add_capture_options(CLI::App& cmd, CaptureArgs& args);
/// Validates the arguments and turns them into options; errors are usage errors (exit 2).
core::Result<CaptureOptions> to_capture_options(const CaptureArgs& args);

/// What the odometry programs (replay, sweep) read and how the odometry runs over it: the same
/// options mean the same to each.
struct OdometryInputArgs {
  std::string capture;  ///< a capture file or a folder of clouds (read_scans)
  double scan_period_s = 0.1;
  std::string mode = "consensus";
  std::string reference = "local-map";
  std::string config;  ///< cndtd configuration file (options given override it)
  CaptureArgs capture_args;
};
/// The input (positional), --scan-period, --mode, --reference, --config and the capture options.
void add_odometry_input_options(CLI::App& cmd, OdometryInputArgs& args);
/// The configuration such a program runs with: the file's (none: the defaults), with the
/// options typed on `command` on top (all of them when it is null), checked as the command
/// line's are.
core::Result<config::Config> odometry_config(const OdometryInputArgs& args,
                                             const CLI::App* command);

struct InfoArgs {
  std::string capture;
  CaptureArgs capture_args;
  bool json = false;
};
void register_info(CLI::App& app, InfoArgs& args);
int run_info(const InfoArgs& args);
std::string format_info_text(const CaptureReport& report);
std::string format_info_json(const CaptureReport& report);

struct DecodeArgs {
  std::string capture;
  std::string out_dir;
  std::string format = "bin";
  bool complete_only = false;
  CaptureArgs capture_args;
};
void register_decode(CLI::App& app, DecodeArgs& args);
int run_decode(const DecodeArgs& args);

struct SimArgs {
  std::string scene = "street";
  double duration_s = 10.0;
  std::string out_dir;
  std::uint64_t seed = 1;
  std::uint64_t world_seed = 0;  ///< 0: the same as seed
  double speed = 0.0;            ///< m/s; 0: the scene's own
  double body_motion = -1.0;     ///< pitch/roll/bounce scale; negative: the scene's own
  std::vector<double> mount;     ///< roll, pitch, yaw of the sensor on the vehicle, degrees
  double height = 0.0;           ///< sensor height above the ground, m; 0: the scene's own
  int movers = 4;
  double drop_rate = 0.0;
  std::vector<double> outage;      // start and length, s
  std::vector<double> clock_step;  // when and by how much, s
  std::vector<double> stop;        // when and how long, s
  double start_still_s = 0.0;      // standing at the start, s
  bool dual = false;
  int rpm = 600;
  double noise_m = 0.01;
  double start_time_s = 1767225600.0;  // 2026-01-01T00:00:00Z
};
void register_sim(CLI::App& app, SimArgs& args);
int run_sim(const SimArgs& args);

struct ReplayArgs {
  OdometryInputArgs input;
  std::string out_dir;
  std::int64_t jitter_seed = 0;  ///< odometry.guess_jitter_seed
  std::size_t max_scans = 0;
  bool mapper = false;
  std::string map;  ///< prior map to localize in
  std::string map_mode = "frozen";
  std::string initial_pose;  ///< x,y,z,roll,pitch,yaw of the first scan in the map frame
  std::string save_map;
  double map_window_m = 0.0;  ///< evict map voxels farther than this from the vehicle; 0 keeps all
  std::string udp_out;        ///< also send every pose as a UDP datagram to ADDRESS:PORT
  bool realtime = false;      ///< pace the capture at its recorded rate
  CLI::App* command = nullptr;  ///< the parsed subcommand: which options were given
};
void register_replay(CLI::App& app, ReplayArgs& args);
int run_replay(const ReplayArgs& args);

struct EvalArgs {
  std::string gt;
  std::string est;
};
void register_eval(CLI::App& app, EvalArgs& args);
int run_eval(const EvalArgs& args);

struct SweepArgs {
  OdometryInputArgs input;
  std::string out_dir;
  std::size_t scan = 10;
  std::vector<std::string> axes{"x", "roll"};
  double max_translation_m = 2.0;
  double max_rotation_deg = 5.0;
  int steps = 20;
  CLI::App* command = nullptr;  ///< the parsed subcommand: which options were given
};
void register_sweep(CLI::App& app, SweepArgs& args);
int run_sweep(const SweepArgs& args);

struct MapArgs {
  enum class Action { kInfo, kExport } action = Action::kInfo;
  std::string file;
  std::string ply;
  std::string pcd;
};
void register_map(CLI::App& app, MapArgs& args);
int run_map(const MapArgs& args);

struct ListenArgs {
  std::uint16_t udp_port = 0;  ///< 0: not listening on UDP
  std::string bind_address = "0.0.0.0";
  std::string candump;  ///< a candump log to decode instead
  std::string dbc;      ///< decode CAN frames with this DBC instead of the built-in layout
  std::uint32_t base_id = 0x300;
  std::uint64_t count = 0;  ///< stop after this many datagrams (0: no limit)
  double timeout_s = 0.0;   ///< stop after this long without a datagram (0: never)
  std::string out;          ///< write the lines here instead of stdout
};
void register_listen(CLI::App& app, ListenArgs& args);
int run_listen(const ListenArgs& args);

struct RecordArgs {
  std::string out;
  std::string bind_address = "0.0.0.0";
  std::uint16_t data_port = 2368;
  std::uint16_t position_port = 8308;
  std::string sensor_ip;
  double duration_s = 0.0;
  std::uint64_t max_packets = 0;
};
void register_record(CLI::App& app, RecordArgs& args);
int run_record(const RecordArgs& args);

}  // namespace cndt::cli
