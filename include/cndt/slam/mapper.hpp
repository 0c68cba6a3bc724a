// The mapper (paper sections 3 and 3.2, eq 7): groups consecutive scans into keyframes by their
// similarity, refines each closed keyframe's scan poses jointly against the map and against each
// other, feeds the map with the refined scans' high-consensus points, and keeps the correction
// T_map_odom that turns later odometry poses into map poses.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <span>
#include <vector>

#include "cndt/ndt/consensus.hpp"
#include "cndt/ndt/ndt_score.hpp"
#include "cndt/ndt/voxel_grid.hpp"
#include "cndt/slam/downsample.hpp"
#include "cndt/slam/ndt_map.hpp"

namespace cndt::slam {

struct MapperOptions {
  MapOptions map;
  /// Most scans a keyframe holds; a keyframe this long closes whatever its similarity.
  std::size_t keyframe_scans = 10;
  /// A keyframe closes when the current scan's similarity to its first scan (voxels occupied in
  /// both over voxels occupied in either, on a similarity_voxel grid) falls below this.
  double keyframe_similarity = 0.5;
  double similarity_voxel = 1.0;  ///< m
  double test_cell = 0.5;         ///< downsampling of a scan's points scored in eq 7, m
  /// Cell the points handed to add() were downsampled to (the odometry's map_cell), m: bounds
  /// the points one voxel can hold, so the chi-square table's size.
  double point_cell = 0.1;
  std::size_t max_scan_points = 150'000;  ///< points a scan brings at most
  std::size_t scan_voxels = 60'000;       ///< capacity of each keyframe scan's own NDT
  double eta = 0.7;        ///< Cv threshold for the voxels eq 7 uses and the map takes
  int max_iterations = 6;  ///< Levenberg-Marquardt iterations per keyframe
  /// Voxels each point of eq 7 is scored against: against the map the voxel it falls in and its
  /// six neighbours (a wider basin); between the keyframe's scans, k (k - 1) terms, the voxel it
  /// falls in (the paper's choice, seven times cheaper).
  ndt::Neighbours map_neighbours = ndt::Neighbours::kSeven;
  /// Eq 7's second sum, every scan against every other scan of the keyframe; without it each
  /// scan is refined against the map alone.
  bool pair_terms = true;
  ndt::Neighbours pair_neighbours = ndt::Neighbours::kOne;
  /// False: the map is not changed (localisation in a frozen prior map); only the poses are
  /// refined against it.
  bool update_map = true;
  /// Evict map voxels outside map.window_radius every this many metres travelled.
  double evict_every = 5.0;
};

/// A scan pose after its keyframe was refined: T_map_sensor at the scan stamp.
struct RefinedPose {
  double stamp = 0.0;  ///< seconds
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  /// Localization consensus Cm (eqs 10-13) of the scan against the map at the refined pose;
  /// NaN while the map is empty.
  double cm = 0.0;
};

struct MapperStats {
  std::size_t keyframes = 0;
  int last_iterations = 0;
  double last_score_before = 0.0, last_score_after = 0.0;
  std::size_t voxels_masked = 0;  ///< reference voxels left out of the last refinement (Cv < eta)
};

class Mapper {
 public:
  explicit Mapper(const MapperOptions& options);
  /// Starts from a prior map (localisation) with the map pose of the odometry frame's origin.
  void start_from(NdtMap&& map, const Eigen::Isometry3d& T_map_odom);
  /// Adds one scan: `points` deskewed, in the sensor frame at the scan stamp; `T_odom_sensor` the
  /// odometry pose. Returns true when this closed a keyframe (the scan then starts the next one).
  bool add(double stamp, const Eigen::Isometry3d& T_odom_sensor,
           std::span<const Eigen::Vector3d> points);
  /// Closes the open keyframe (end of input).
  void flush();
  /// Map pose of the odometry frame, from the last refined keyframe.
  [[nodiscard]] const Eigen::Isometry3d& correction() const { return T_map_odom_; }
  /// The refined poses of the keyframe closed by the last add() or flush().
  [[nodiscard]] std::span<const RefinedPose> refined() const { return refined_; }
  [[nodiscard]] const NdtMap& map() const { return map_; }
  [[nodiscard]] const MapperStats& stats() const { return stats_; }
  /// Eq 7 for the open keyframe's scans at `poses` (T_map_sensor, one per open scan), with the
  /// Cv masks of their current poses; with g and H also its gradient and the Hessian the
  /// refinement uses, for steps T exp(d), d = (translation, rotation vector), of every scan.
  /// The keyframe close runs the same code; tests check it against finite differences.
  double eq7(const std::vector<Eigen::Isometry3d>& poses, Eigen::VectorXd* g = nullptr,
             Eigen::MatrixXd* H = nullptr);
  [[nodiscard]] std::size_t open_scans() const { return open_; }

 private:
  struct KeyframeScan {
    double stamp = 0.0;
    Eigen::Isometry3d odom = Eigen::Isometry3d::Identity();  // T_odom_sensor
    Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();  // T_map_sensor, being refined
    std::vector<Eigen::Vector3d> points;                     // sensor frame, all
    std::vector<Eigen::Vector3d> test;                       // sensor frame, at test_cell
    ndt::VoxelGrid grid;                                     // NDT of `points`, sensor frame
    std::vector<std::uint8_t> mask;                          // grid voxels with Cv >= eta
    explicit KeyframeScan(const MapperOptions& o);
  };
  double similarity(const Eigen::Isometry3d& T_odom_sensor,
                    std::span<const Eigen::Vector3d> points);
  void close_keyframe();
  void prepare_keyframe();  // each scan's NDT and the Cv masks
  void linearize(const std::vector<Eigen::Isometry3d>& poses, std::size_t first_free,
                 Eigen::MatrixXd& H, Eigen::VectorXd& g) const;
  void compute_masks();
  double total_score(const std::vector<Eigen::Isometry3d>& poses) const;
  int refine();
  // Cm of each refined scan against the map, and (with update_map) the map update.
  void score_and_update_map();

  MapperOptions options_;
  NdtMap map_;
  std::vector<std::uint8_t> map_mask_;
  std::vector<KeyframeScan> scans_;             // capacity keyframe_scans, reused
  std::size_t open_ = 0;                        // scans in the open keyframe
  ndt::VoxelGrid first_occupancy_, occupancy_;  // similarity grids (odometry frame)
  ndt::ChiSquareTable chi2_;
  ndt::VoxelResiduals residuals_;
  std::vector<double> cv_;
  Downsampler test_sampler_;
  Eigen::Isometry3d T_map_odom_ = Eigen::Isometry3d::Identity();
  std::vector<RefinedPose> refined_;
  MapperStats stats_;
  Eigen::Vector3d last_evict_ = Eigen::Vector3d::Constant(1e300);
};

}  // namespace cndt::slam
