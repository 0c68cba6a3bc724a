// The runtime of cndtd and `cndt replay` (docs/architecture.md): scans enter through a pool of
// preallocated slots and a lock-free SPSC ring, a fixed-memory odometry thread matches them and
// publishes every pose, a lower-priority mapper thread refines keyframes and hands the
// correction T_map_odom back through another ring, and per-scan results leave through a third
// ring to whoever writes files or health lines.
//
// Two modes. Live (the daemon on a sensor): the input never waits; when the scan ring is full
// the oldest scan is dropped and counted, and the odometry applies whatever correction the mapper
// has finished. Replay: back-pressure instead of drops, and each scan's pose is published with the
// correction the mapper had right after taking that scan, so that every run of a capture gives
// the same bytes; the odometry meanwhile goes on with the next scans (up to keyframe_ring ahead).
#pragma once

#include <Eigen/Geometry>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <thread>
#include <vector>

#include "cndt/core/scan.hpp"
#include "cndt/runtime/publisher.hpp"
#include "cndt/runtime/realtime.hpp"
#include "cndt/slam/mapper.hpp"
#include "cndt/slam/odometry.hpp"

namespace cndt::runtime {

struct PipelineOptions {
  slam::OdometryOptions odometry;
  bool mapper = false;
  slam::MapperOptions mapper_options;
  std::size_t scan_ring = 4;       ///< scans waiting for the odometry
  std::size_t keyframe_ring = 64;  ///< scans waiting for the mapper
  /// Points those scans hold together (one buffer; at least max_scan_points). Live: a scan
  /// that does not fit is not handed to the mapper (mapper_dropped); replay waits for room.
  std::size_t keyframe_ring_points = 1'500'000;
  std::size_t result_ring = 1024;  ///< results waiting for the consumer
  /// Time constant (s) with which published poses follow a new map correction (0 = at once;
  /// slam::CorrectionBlend).
  double correction_time_constant = 0.0;
  bool live = false;              ///< drop the oldest scan on a full ring (else wait)
  std::size_t warmup_scans = 20;  ///< allocations on the odometry thread count after these
  ThreadSetup odometry_thread;
  ThreadSetup mapper_thread;
  /// Threads that score a scan's points against the reference: the odometry thread and
  /// scoring_threads - 1 helpers (ScoreThreads), set up like the odometry thread but not
  /// pinned. The poses do not depend on it.
  std::size_t scoring_threads = 1;
};

/// What the odometry thread reports for each scan.
struct ScanResult {
  slam::OdometryResult odometry;
  Eigen::Isometry3d published = Eigen::Isometry3d::Identity();  ///< the pose sent out
  bool map_corrected = false;
  bool published_pose = false;  ///< false for a skipped scan (no pose)
  std::uint64_t sequence = 0;   ///< the scan's sequence number
  double odometry_ms = 0.0;     ///< time in the odometry for this scan (estimate and commit)
  double latency_ms = 0.0;      ///< from the scan's completion to its pose being published
};

struct PipelineStats {
  std::uint64_t scans_in = 0;         ///< handed to push()
  std::uint64_t scans_dropped = 0;    ///< dropped because the scan ring was full (live)
  std::uint64_t scans_done = 0;       ///< processed by the odometry
  std::uint64_t mapper_dropped = 0;   ///< not handed to the mapper: its ring was full (live)
  std::uint64_t results_dropped = 0;  ///< results the consumer did not take in time (live)
  std::uint64_t keyframes = 0;
  /// Heap allocations on the odometry thread after warmup_scans (the whole loop: matching,
  /// publishing, ring traffic).
  std::uint64_t heap_allocations_in_odometry = 0;
  /// Page faults (minor and major) of the odometry thread over the same scans: every buffer is
  /// written once at start-up (core/resident.hpp), so after warm-up the thread should neither
  /// map in new memory nor grow the process's resident size.
  std::uint64_t page_faults_in_odometry = 0;
  bool allocations_counted = false;  ///< warm-up is over
};

class Pipeline {
 public:
  /// Allocates every buffer: scan slots of `max_scan_points`, rings, odometry and mapper state.
  Pipeline(const PipelineOptions& options, std::size_t max_scan_points, PosePublisher& publisher);
  ~Pipeline();
  Pipeline(const Pipeline&) = delete;
  Pipeline& operator=(const Pipeline&) = delete;

  /// Before start(): localize in a prior map (the mapper must be on).
  void start_from(slam::NdtMap&& map, const Eigen::Isometry3d& T_map_odom);
  /// Before start(): called on the mapper thread after each closed keyframe (and after the
  /// last one, closed at the end of input), with the milliseconds the closing took.
  void on_keyframe(std::function<void(const slam::Mapper&, double ms)> callback);
  /// Before start(): called on the odometry thread after each scan (must not allocate).
  void on_scan_done(void (*callback)(void*), void* context);
  /// Before start(): called on the mapper thread after each scan it took, once the scan's slot
  /// is back in the pool and before it takes the next.
  void on_mapper_scan_done(void (*callback)(void*), void* context);

  void start();

  /// Input side (one thread): hands over a completed scan (copied into a slot). Replay mode
  /// waits for room. Live mode never waits: when the ring is full the scan is held on the input
  /// side and the odometry drops the oldest ring scan at its next step to make room. False
  /// once stop() was called.
  bool push(const core::Scan& scan, std::chrono::steady_clock::time_point completed);
  /// Live input side: moves held scans into the ring as it makes room (call after each packet).
  void service_input();
  /// No more input. drain: the odometry processes every queued scan; otherwise only the scan
  /// in hand (a shutdown). The mapper then closes its open keyframe.
  void close_input(bool drain);
  /// Stops waiting producers too (push returns false).
  void stop();

  /// Result side (one thread): the next result, if one is ready.
  bool pop(ScanResult& out);
  /// Both threads have finished (after close_input) and every result was popped.
  [[nodiscard]] bool done() const;
  /// Waits for the threads (after close_input); results still queued stay poppable.
  void join();

  [[nodiscard]] PipelineStats stats() const;
  /// The mapper (after join(); null without one).
  [[nodiscard]] slam::Mapper* mapper() { return mapper_.get(); }

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
  std::unique_ptr<slam::Mapper> mapper_;
};

}  // namespace cndt::runtime
