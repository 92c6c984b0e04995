// The paper's simulation experiments (Section 3.1, Tables 1-3, Fig. 4) end to end.
//
// One run (RunSimulationOnce): build the world of the scenario, simulate robots and sensing
// (sim/), run multi-robot object SLAM with rendezvous (slam/multi_robot.h), assemble the joint
// graph, then
//   - centralized: Levenberg-Marquardt (solver default, lambda 1e-10: the Gauss-Newton step
//     wherever it lowers the cost) started from the centralized two-stage estimate
//     (CentralizedTwoStage: the fixed point DGS converges to, as the DGS paper initialises its
//     GN); also, for comparison only, the same solver from ChordalInitialization (gn_chordal_cost).
//     At 15 deg / 0.3 m the joint problem has several local minima: over Table 2's 10 runs the
//     two starts differed by -2.3% to +4.2% in single runs (README);
//   - DGS (distributed/dgs_driver.h) with eta = 1e-1 and eta = 1e-2 (both stages), from each
//     robot's own estimate; iterations = rotation sweeps + pose sweeps; two-level (coarse
//     correction, ExperimentConfig::two_level_dgs) by default, the one-level DGS of the paper
//     run beside it for its sweep counts;
//   - refined: the DGS refinement stage (Gauss-Newton by distributed sweeps) run after the
//     eta = 1e-2 two-stage estimate (DgsOptions::refine). From the coarser eta = 1e-1 estimate
//     it reached a worse local minimum in 1 of 10 runs at 15 deg / 0.3 m (+4.2%);
//   - ATE*/ARE* (CompareEstimates, no alignment) of DGS eta = 1e-1 against the centralized
//     estimate, poses and landmarks, as the paper; ATE/ARE against ground truth after the rigid
//     alignment (CompareToGroundTruth) for the centralized and DGS estimates;
//   - association precision/recall (intra-robot and rendezvous), bytes of the rendezvous messages
//     and of the DGS messages; per-robot memory and communication (Table 3, below).
// All costs are F = sum 1/2 r^T Omega r of the joint graph (CONVENTIONS.md).
//
// Information (the Omega of every factor of the joint graph):
//   kNoise  Omega = diag(1/sigma_R^2 I3, 1/sigma_t^2 I3) of the simulated noise (statistically
//           right; the cost is then about the number of residual degrees of freedom / 2 at every
//           noise level).
//   kFixed  Omega of the paper's default noise (5 deg, 0.2 m) whatever noise is simulated: the
//           cost then grows with the noise (x noise^2 for a near-linear problem) as the paper's
//           Table 2 GN column does (160.9 -> 643.4 -> 1447.2 for noise x1, x2, x3): this is the
//           mode that reproduces the paper's trend (README, Table 2).
//
// Randomness: run i of a config uses seed + i for the world (chairs25 yaws, generated layout),
// the trajectories and the sensing, so a config and seed give the same numbers bit for bit
// (wall times aside).
//
// Table 3 (paper Section 3.2), per robot, in bytes:
//   memory     point cloud  n_f K C        (n_f frames = poses, K points per frame, C bytes/point)
//              object map   n_o P C        (n_o the robot's landmarks, P points per object model)
//              measured     the robot's serialized object map (slam/rendezvous.h EncodeObjectMap)
//   comm.      point cloud  n_c K C        (n_c rendezvous the robot took part in)
//              object map   n_o L          (L bytes per object: label and pose)
//              measured     the rendezvous messages the robot sent (serialized), and its share
//                           of the DGS traffic (total DGS bytes eta 1e-1 / robots)
#pragma once

#include "moslam/common/errors.h"

#include <cstdint>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include "moslam/graph/pose_graph.h"

namespace moslam {

struct SimulationData;  // sim/sensing.h
struct RunMetrics;

enum class InformationMode { kNoise, kFixed };
std::string ToString(InformationMode mode);
// "noise" | "fixed"; throws InvalidInputError otherwise.
InformationMode InformationModeFromString(const std::string& text);

struct PointCloudModel {   // the paper's Table 3 formulas
  double points_per_frame = 640.0 * 480.0;  // K: one VGA depth frame
  double bytes_per_point = 32.0;            // C: pcl::PointXYZRGB (x, y, z, pad, rgb, pad)
  double points_per_object = 10000.0;       // P: points of one object model
  double bytes_per_object = 32.0;           // L: label (4 bytes) + pose (7 floats)
};

struct ExperimentConfig {
  std::string scenario = "chairs25";  // chairs25 | house | generated
  int robots = 6;
  int runs = 10;
  unsigned seed = 1;
  double sigma_rotation_deg = 5.0;   // odometry and object measurements alike
  double sigma_translation = 0.2;    // m
  InformationMode information = InformationMode::kNoise;
  int poses_per_robot = 100;
  bool refine = true;                // run the DGS refinement (refined cost)
  // Whether a rendezvous knows the robots' initial poses (the paper) or aligns the two object
  // maps from the objects alone (slam/rendezvous.h).
  bool known_initial_poses = true;
  // Wrong associations injected at rendezvous (MultiRobotSlamConfig::outlier_fraction; seeded by
  // the run's seed), and the robust distributed solve (distributed/robust_dgs.h) run beside the
  // least-squares one, with the outlier-free solve (the wrong object-object factors removed by
  // ground truth) as reference.
  double outlier_fraction = 0.0;
  bool robust = false;
  // GNC's threshold on r^T Omega r of an object-object factor (0: GncOptions' default).
  double gnc_threshold = 0.0;
  // RobustDgsOptions::retest_left_out and retest_groups.
  bool retest_left_out = true;
  bool retest_groups = true;
  // RobustDgsOptions::one_to_one_after_gnc.
  bool one_to_one_after_gnc = false;
  // The robots' landmark exclusion radius (ObjectSlamConfig::exclusion_radius; m, 0: off). `moslam
  // simulate` sets 0.5 m with --perception rendered: the front-end confuses a chair with its
  // quarter and half turns, which sampled measurements never do.
  double exclusion_radius = 0.0;
  // The robots' leave-one-out check of their matches (ObjectSlamConfig::leave_one_out_check;
  // `moslam simulate --leave-one-out-check`).
  bool leave_one_out_check = false;
  // The robots' refusal of ambiguous matches (ObjectSlamConfig::ambiguity_ratio; 0: off, the
  // paper's rule). `moslam simulate` sets kRenderedAmbiguityRatio with --perception rendered.
  double ambiguity_ratio = 0.0;
  // The robots' covariance gate (ObjectSlamConfig::covariance_gate; 0: off, the paper's fixed
  // gate; `moslam simulate --covariance-gate CHI2`).
  double covariance_gate = 0.0;
  // The robots' loop closure by object constellations (ObjectSlamConfig::loop_closure). Off
  // here (the paper's rule); `moslam simulate` turns it on with --perception rendered unless
  // --no-loop-closure.
  bool loop_closure = false;
  // The rendezvous' refinement by the constellation of both object maps
  // (RendezvousConfig::refine_by_constellation; known initial poses). Off here; `moslam simulate`
  // turns it on with --perception rendered unless --no-rendezvous-constellation.
  bool rendezvous_constellation = false;
  // A run in which some robot never gets linked to robot 0 (no rendezvous aligned, or, with
  // robust, the separator check refused all its links) is left out of the mean and counted
  // (ExperimentResult::skipped), instead of failing the experiment.
  bool skip_unlinked = false;
  // The DGS of the tables: two-level (DgsOptions::coarse_correction, the default) or one-level
  // (the paper's). The other one runs too, for its sweep counts only (iterations_*_other).
  bool two_level_dgs = true;
  PointCloudModel point_cloud;
  // Object measurements by another front-end instead of the sampled ones (sim/sensing.h): called
  // once per run after the simulation, it replaces data.measurements[r].detections and fills the
  // perception_* fields of the run's metrics. Null: sampled. The perception front-end on
  // rendered frames provides one (perception/rendered_sensing.h, `moslam simulate --perception
  // rendered`); this library does not depend on it.
  using Perceive = std::function<void(SimulationData& data, RunMetrics& metrics)>;
  Perceive perceive;
  // The name the results give the measurements when `perceive` is set (`moslam simulate
  // --perception`: rendered, visible); without it, they are sampled.
  std::string perception = "rendered";
  // Throws InvalidInputError naming the first bad field.
  void validate() const;
};

// Everything measured in one run (or, in ExperimentResult::mean, averaged over the runs).
struct RunMetrics {
  static constexpr double kNotRun = std::numeric_limits<double>::quiet_NaN();
  double poses = 0, landmarks = 0, shared_objects = 0, rendezvous = 0;
  // DGS, eta = 1e-1 and 1e-2: sweeps (rotation + pose) and cost; bytes of the DGS messages.
  double iterations_eta1 = 0, cost_eta1 = 0, iterations_eta2 = 0, cost_eta2 = 0;
  double dgs_bytes_eta1 = 0, dgs_bytes_eta2 = 0;
  // The sweeps of the other DGS variant (one-level when the tables use two-level, and back).
  double iterations_eta1_other = 0, iterations_eta2_other = 0;
  double gn_cost = 0, gn_iterations = 0;
  double gn_chordal_cost = 0;  // the same solver started from ChordalInitialization instead
  // After the refinement of the eta = 1e-2 estimate (NaN when not run).
  double refined_cost = 0, refine_iterations = 0, refine_bytes = 0;
  // ATE*/ARE* of DGS eta = 1e-1 against the centralized estimate.
  double ate_star_poses = 0, ate_star_landmarks = 0, are_star_poses = 0, are_star_landmarks = 0;
  // Against ground truth after alignment.
  double gn_ate_poses = 0, gn_ate_landmarks = 0, gn_are_poses = 0, gn_are_landmarks = 0;
  double dgs_ate_poses = 0, dgs_ate_landmarks = 0, dgs_are_poses = 0, dgs_are_landmarks = 0;
  // Association against ground truth.
  double intra_precision = 0, intra_recall = 0, inter_precision = 0, inter_recall = 0;
  // Detections the robots discarded (ObjectSlamConfig::exclusion_radius) and matches they refused
  // (ObjectSlamConfig::leave_one_out_check; their detections discarded too).
  double intra_discarded = 0, intra_refused = 0;
  // Object-object factors of the robots' loop closures (ObjectSlamConfig::loop_closure), and the
  // wrong ones (landmarks created for two world objects).
  double intra_loop_closures = 0, intra_wrong_loop_closures = 0;
  double rendezvous_bytes = 0;  // all rendezvous messages
  // Unknown initial poses: rendezvous aligned, refused (too few consistent objects, ambiguous,
  // contradicted by the overlap check), accepted with mostly wrong pairs; the rendezvous where
  // both robots had mapped 4 or more common objects, and how many of those were aligned.
  // Consistency across rendezvous: pairs removed, and the right ones among them.
  double aligned = 0, refused_too_few = 0, refused_ambiguous = 0, refused_contradicted = 0;
  double alignments_wrong = 0;
  double alignable = 0, alignable_aligned = 0;
  double shared_removed = 0, shared_removed_correct = 0;
  // Robust solve (ExperimentConfig::robust): object-object factors that are wrong (injected or
  // found), the robust solve's outlier precision and recall over them; the same for the
  // object-pose factors (observations) wrongly associated in a robot's own map, and for the
  // object-object factors of the robots' own loop closures (ExperimentConfig::loop_closure; in
  // the JSON and on `moslam simulate`'s stderr); ground-truth errors of the least-squares DGS
  // (refined), of the robust DGS and of the outlier-free solve (every wrong factor of the three
  // kinds removed), the robust estimate against the outlier-free one (same gauge, no alignment),
  // the robust estimate against the least-squares one (the "the same estimate to 1e-6 m"
  // with no outlier), and the robust solve's traffic (all of it; the weights and its checks
  // alone).
  double injected = 0, wrong_factors = 0, outlier_precision = 0, outlier_recall = 0;
  double wrong_observations = 0, observation_precision = 0, observation_recall = 0;
  double wrong_loop_closure_factors = 0, loop_closure_precision = 0, loop_closure_recall = 0;
  double ls_ate_poses = 0, ls_are_poses = 0, robust_ate_poses = 0, robust_are_poses = 0;
  double free_ate_poses = 0, free_are_poses = 0;
  double robust_vs_free_ate = 0, robust_vs_free_are = 0;
  double robust_vs_ls_ate = 0, robust_vs_ls_are = 0;
  double robust_bytes = 0, robust_extra_bytes = 0, robust_rounds = 0;
  // Table 3, per robot (bytes), averaged over the robots.
  double memory_pcd = 0, memory_obj_formula = 0, memory_obj_measured = 0;
  double comm_pcd = 0, comm_obj_formula = 0, comm_obj_measured = 0, comm_dgs_per_robot = 0;
  // Perception on rendered frames (ExperimentConfig::rendered; NaN with sampled measurements):
  // frames perceived, detections, true ones (IoU >= 0.5 with a same-label object), accepted
  // registrations (and true ones), rejections by the 12-inlier gate (and false detections among
  // them), median pose error of the accepted true ones, milliseconds per frame per stage;
  // true detections of objects with >= 30 % of their silhouette seen, and accepted ones
  // (RenderedSensingConfig::min_visible_fraction).
  double perception_frames = kNotRun, perception_detections = kNotRun,
         perception_true_detections = kNotRun, perception_accepted = kNotRun,
         perception_accepted_true = kNotRun, perception_rejected_inliers = kNotRun,
         perception_rejected_inliers_false = kNotRun, perception_median_error_m = kNotRun,
         perception_median_error_deg = kNotRun, perception_ms_render = kNotRun,
         perception_ms_detect = kNotRun, perception_ms_segment = kNotRun,
         perception_ms_register = kNotRun, perception_true_visible = kNotRun,
         perception_accepted_visible = kNotRun;
  // Per robot: the point clouds of the perceived frames (valid depth points x
  // PointCloudModel::bytes_per_point), against memory_obj_measured (the object map).
  double perception_pcd_bytes = kNotRun;
  // 1 when the run's perception was replayed from a cache (experiments/perception_cache.h: its
  // perception_* timings are then those of the run that filled it), 0 when perceived.
  double perception_cached = kNotRun;
  // The poses' object measurements (sampled or perceived): per pose, the share of poses with
  // none, and the most consecutive poses of one robot with none (MeasurementCoverage,
  // sim/sensing.h).
  double measurements_per_pose = 0, poses_without_measurement = 0,
         longest_without_measurement = 0;
  // Wall time (s).
  double seconds_slam = 0, seconds_gn = 0, seconds_dgs_eta1 = 0, seconds_refine = 0, seconds = 0;
};

// The estimates of one run, for plots (robot 0's frame).
struct RunEstimates {
  Values ground_truth, centralized, dgs;  // dgs: eta = 1e-1 two-stage estimate
  int robots = 0;
};

// A run in which some robot never got linked to robot 0 through rendezvous (or through the
// separators the robust solve's check kept).
class UnlinkedRobotError : public UnderdeterminedError {
 public:
  using UnderdeterminedError::UnderdeterminedError;
};

struct ExperimentResult {
  ExperimentConfig config;
  std::vector<RunMetrics> runs;
  std::vector<int> skipped;  // runs left out (ExperimentConfig::skip_unlinked)
  RunMetrics mean;
};

// One run with seed config.seed + run. Throws the errors of the modules it drives.
RunMetrics RunSimulationOnce(const ExperimentConfig& config, int run,
                             RunEstimates* estimates = nullptr);
// config.runs runs and their mean. `first_estimates`: the estimates of run 0.
ExperimentResult RunExperiment(const ExperimentConfig& config,
                               RunEstimates* first_estimates = nullptr);

RunMetrics MeanOf(const std::vector<RunMetrics>& runs);

enum class TableKind { kAccuracy, kAssociation, kMemory, kScale, kPerception, kRobust };
// "accuracy" | "association" | "memory" | "scale" | "perception" | "robust"; throws
// InvalidInputError otherwise.
TableKind TableKindFromString(const std::string& text);

// One Markdown table, one row per result (its mean), with a header for `kind`.
std::string FormatMarkdownTable(const std::vector<ExperimentResult>& results, TableKind kind);
// {"rows": [{"config": {...}, "mean": {...}, "runs": [{...}, ...]}, ...]} on one line.
std::string ResultsToJson(const std::vector<ExperimentResult>& results);

// SVG like the paper's Fig. 4 (x-y plane): per robot a polyline of the centralized trajectory
// (solid) and of the DGS one (dashed), landmarks as circles (centralized filled, DGS open).
std::string PlotSvg(const RunEstimates& estimates, const std::string& title);

}  // namespace moslam
