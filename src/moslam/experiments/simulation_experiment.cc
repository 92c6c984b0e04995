#include "moslam/experiments/simulation_experiment.h"

#include "moslam/experiments/simulated_run.h"

#include <fmt/core.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>
#include <utility>

#include "moslam/common/errors.h"
#include "moslam/distributed/centralized_two_stage.h"
#include "moslam/distributed/dgs_driver.h"
#include "moslam/distributed/robust_dgs.h"
#include "moslam/metrics/metrics.h"
#include "moslam/robust/gnc.h"
#include "moslam/sim/sensing.h"
#include "moslam/sim/world.h"
#include "moslam/slam/multi_robot.h"
#include "moslam/slam/rendezvous.h"
#include "moslam/solver/initialization.h"
#include "moslam/solver/optimizer.h"

namespace moslam {
namespace {

// Ground-truth errors of an estimate; NaN ("n/a" in the tables) when it has collapsed: its pose
// positions collinear or coincident, so no rigid alignment exists (the robust estimate of one
// run on generated with 64 robots and 70 % wrong associations: GNC failed there). The run then
// shows in its row instead of ending the whole experiment.
GroundTruthErrors CompareToGroundTruthOrNan(const Values& estimate, const Values& truth) {
  try {
    return CompareToGroundTruth(estimate, truth);
  } catch (const UnderdeterminedError&) {
    GroundTruthErrors collapsed;
    const ErrorStats nan{std::nan(""), std::nan(""), 0};
    for (TrajectoryErrors* t : {&collapsed.aligned, &collapsed.unaligned}) {
      t->poses = nan;
      t->objects = nan;
    }
    return collapsed;
  }
}

using Clock = std::chrono::steady_clock;
double SecondsSince(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// Every field of RunMetrics, for the mean and the JSON.
const std::vector<std::pair<const char*, double RunMetrics::*>>& Fields() {
  static const std::vector<std::pair<const char*, double RunMetrics::*>> fields = {
      {"poses", &RunMetrics::poses},
      {"landmarks", &RunMetrics::landmarks},
      {"shared_objects", &RunMetrics::shared_objects},
      {"rendezvous", &RunMetrics::rendezvous},
      {"iterations_eta1", &RunMetrics::iterations_eta1},
      {"cost_eta1", &RunMetrics::cost_eta1},
      {"iterations_eta2", &RunMetrics::iterations_eta2},
      {"cost_eta2", &RunMetrics::cost_eta2},
      {"dgs_bytes_eta1", &RunMetrics::dgs_bytes_eta1},
      {"dgs_bytes_eta2", &RunMetrics::dgs_bytes_eta2},
      {"iterations_eta1_other", &RunMetrics::iterations_eta1_other},
      {"iterations_eta2_other", &RunMetrics::iterations_eta2_other},
      {"gn_cost", &RunMetrics::gn_cost},
      {"gn_iterations", &RunMetrics::gn_iterations},
      {"gn_chordal_cost", &RunMetrics::gn_chordal_cost},
      {"refined_cost", &RunMetrics::refined_cost},
      {"refine_iterations", &RunMetrics::refine_iterations},
      {"refine_bytes", &RunMetrics::refine_bytes},
      {"ate_star_poses", &RunMetrics::ate_star_poses},
      {"ate_star_landmarks", &RunMetrics::ate_star_landmarks},
      {"are_star_poses", &RunMetrics::are_star_poses},
      {"are_star_landmarks", &RunMetrics::are_star_landmarks},
      {"gn_ate_poses", &RunMetrics::gn_ate_poses},
      {"gn_ate_landmarks", &RunMetrics::gn_ate_landmarks},
      {"gn_are_poses", &RunMetrics::gn_are_poses},
      {"gn_are_landmarks", &RunMetrics::gn_are_landmarks},
      {"dgs_ate_poses", &RunMetrics::dgs_ate_poses},
      {"dgs_ate_landmarks", &RunMetrics::dgs_ate_landmarks},
      {"dgs_are_poses", &RunMetrics::dgs_are_poses},
      {"dgs_are_landmarks", &RunMetrics::dgs_are_landmarks},
      {"intra_precision", &RunMetrics::intra_precision},
      {"intra_recall", &RunMetrics::intra_recall},
      {"intra_discarded", &RunMetrics::intra_discarded},
      {"intra_refused", &RunMetrics::intra_refused},
      {"intra_loop_closures", &RunMetrics::intra_loop_closures},
      {"intra_wrong_loop_closures", &RunMetrics::intra_wrong_loop_closures},
      {"wrong_loop_closure_factors", &RunMetrics::wrong_loop_closure_factors},
      {"loop_closure_precision", &RunMetrics::loop_closure_precision},
      {"loop_closure_recall", &RunMetrics::loop_closure_recall},
      {"inter_precision", &RunMetrics::inter_precision},
      {"inter_recall", &RunMetrics::inter_recall},
      {"rendezvous_bytes", &RunMetrics::rendezvous_bytes},
      {"aligned", &RunMetrics::aligned},
      {"refused_too_few", &RunMetrics::refused_too_few},
      {"refused_ambiguous", &RunMetrics::refused_ambiguous},
      {"refused_contradicted", &RunMetrics::refused_contradicted},
      {"alignments_wrong", &RunMetrics::alignments_wrong},
      {"alignable", &RunMetrics::alignable},
      {"alignable_aligned", &RunMetrics::alignable_aligned},
      {"shared_removed", &RunMetrics::shared_removed},
      {"shared_removed_correct", &RunMetrics::shared_removed_correct},
      {"injected", &RunMetrics::injected},
      {"wrong_factors", &RunMetrics::wrong_factors},
      {"outlier_precision", &RunMetrics::outlier_precision},
      {"outlier_recall", &RunMetrics::outlier_recall},
      {"wrong_observations", &RunMetrics::wrong_observations},
      {"observation_precision", &RunMetrics::observation_precision},
      {"observation_recall", &RunMetrics::observation_recall},
      {"ls_ate_poses", &RunMetrics::ls_ate_poses},
      {"ls_are_poses", &RunMetrics::ls_are_poses},
      {"robust_ate_poses", &RunMetrics::robust_ate_poses},
      {"robust_are_poses", &RunMetrics::robust_are_poses},
      {"free_ate_poses", &RunMetrics::free_ate_poses},
      {"free_are_poses", &RunMetrics::free_are_poses},
      {"robust_vs_free_ate", &RunMetrics::robust_vs_free_ate},
      {"robust_vs_free_are", &RunMetrics::robust_vs_free_are},
      {"robust_vs_ls_ate", &RunMetrics::robust_vs_ls_ate},
      {"robust_vs_ls_are", &RunMetrics::robust_vs_ls_are},
      {"robust_bytes", &RunMetrics::robust_bytes},
      {"robust_extra_bytes", &RunMetrics::robust_extra_bytes},
      {"robust_rounds", &RunMetrics::robust_rounds},
      {"memory_pcd", &RunMetrics::memory_pcd},
      {"memory_obj_formula", &RunMetrics::memory_obj_formula},
      {"memory_obj_measured", &RunMetrics::memory_obj_measured},
      {"comm_pcd", &RunMetrics::comm_pcd},
      {"comm_obj_formula", &RunMetrics::comm_obj_formula},
      {"comm_obj_measured", &RunMetrics::comm_obj_measured},
      {"comm_dgs_per_robot", &RunMetrics::comm_dgs_per_robot},
      {"perception_frames", &RunMetrics::perception_frames},
      {"perception_detections", &RunMetrics::perception_detections},
      {"perception_true_detections", &RunMetrics::perception_true_detections},
      {"perception_accepted", &RunMetrics::perception_accepted},
      {"perception_accepted_true", &RunMetrics::perception_accepted_true},
      {"perception_true_visible", &RunMetrics::perception_true_visible},
      {"perception_accepted_visible", &RunMetrics::perception_accepted_visible},
      {"perception_rejected_inliers", &RunMetrics::perception_rejected_inliers},
      {"perception_rejected_inliers_false", &RunMetrics::perception_rejected_inliers_false},
      {"perception_median_error_m", &RunMetrics::perception_median_error_m},
      {"perception_median_error_deg", &RunMetrics::perception_median_error_deg},
      {"perception_ms_render", &RunMetrics::perception_ms_render},
      {"perception_ms_detect", &RunMetrics::perception_ms_detect},
      {"perception_ms_segment", &RunMetrics::perception_ms_segment},
      {"perception_ms_register", &RunMetrics::perception_ms_register},
      {"perception_pcd_bytes", &RunMetrics::perception_pcd_bytes},
      {"perception_cached", &RunMetrics::perception_cached},
      {"measurements_per_pose", &RunMetrics::measurements_per_pose},
      {"poses_without_measurement", &RunMetrics::poses_without_measurement},
      {"longest_without_measurement", &RunMetrics::longest_without_measurement},
      {"seconds_slam", &RunMetrics::seconds_slam},
      {"seconds_gn", &RunMetrics::seconds_gn},
      {"seconds_dgs_eta1", &RunMetrics::seconds_dgs_eta1},
      {"seconds_refine", &RunMetrics::seconds_refine},
      {"seconds", &RunMetrics::seconds},
  };
  return fields;
}

// The joint graph with every factor's information replaced by `information`.
PoseGraph WithInformation(const PoseGraph& graph, const Matrix6& information) {
  PoseGraph out;
  for (const auto& f : graph.factors()) {
    out.add(RelativePoseFactor(f.a(), f.b(), f.measured(), information));
  }
  for (const auto& p : graph.priors()) out.add(p);
  return out;
}

struct DgsRun {
  Values values;
  double iterations = 0, bytes = 0, seconds = 0;
  double refined_cost = kNaN, refine_iterations = kNaN, refine_bytes = kNaN, refine_seconds = kNaN;
};

DgsRun RunDgsStages(const PoseGraph& graph, const Values& initial, double eta, bool refine,
                    bool two_level) {
  DgsOptions options;
  options.eta_rotation = eta;
  options.eta_pose = eta;
  options.refine = refine;
  options.coarse_correction = two_level;
  const auto t0 = Clock::now();
  DgsDriver driver(graph, initial, options);
  const DgsStageReport rotation = driver.runRotationStage();
  const DgsStageReport pose = driver.runPoseStage();
  DgsRun run;
  const DgsResult two_stage = driver.result();
  run.values = two_stage.values;
  run.iterations = rotation.iterations + pose.iterations;
  run.bytes = static_cast<double>(two_stage.bytes);
  run.seconds = SecondsSince(t0);
  if (refine) {
    const auto t1 = Clock::now();
    const RefineReport report = driver.runRefineStage();
    run.refined_cost = graph.cost(driver.result().values);
    run.refine_iterations = report.iterations;
    run.refine_bytes = static_cast<double>(report.bytes);
    run.refine_seconds = SecondsSince(t1);
  }
  return run;
}

std::string Sci(double v) { return std::isfinite(v) ? fmt::format("{:.1e}", v) : "n/a"; }
std::string Fix(double v, int digits = 1) {
  return std::isfinite(v) ? fmt::format("{:.{}f}", v, digits) : "n/a";
}
std::string MB(double bytes) { return Sci(bytes / 1e6); }

// The robust factors of the joint graph (ObjectFactors, as the robot processes), of three kinds,
// and which are wrong. The object-object factors between robots and those of a robot's own loop
// closures, wrong when their landmarks are other world objects; the object-pose factors, wrong
// when the detection is of another object than its landmark's (a wrong association inside the
// robot's own map, as the intra-association errors of Table 2). A landmark stands for the world
// object most of its observations are of (ties: the one that created it): a wrong association
// inside a map can outnumber the right ones.
struct FactorTruth {
  enum class Kind { kOther, kSeparator, kObservation, kLoopClosure };
  std::vector<bool> robust;
  std::vector<Kind> kind;
  std::vector<bool> wrong;
  std::vector<RelativePoseFactor> right;  // the factors not wrong: the outlier-free graph
};

FactorTruth ClassifyFactors(const JointProblem& joint, const MultiRobotSlamResult& slam) {
  using Kind = FactorTruth::Kind;
  const std::size_t nf = joint.graph.factors().size();
  const std::map<Key, int> truth_of = LandmarkObjects(joint, slam.robots);
  FactorTruth t;
  t.robust = ObjectFactors(joint.graph);
  t.kind.assign(nf, Kind::kOther);
  t.wrong.assign(nf, false);
  for (std::size_t i = 0; i < nf; ++i) {
    const RelativePoseFactor& f = joint.graph.factors()[i];
    if (f.a().isObject() && f.b().isObject()) {
      t.kind[i] = f.a().robot != f.b().robot ? Kind::kSeparator : Kind::kLoopClosure;
      t.wrong[i] = WrongPair(truth_of, f.a(), f.b());
    } else if (joint.factor_objects[i] != ObjectSlam::kNoObservation) {
      t.kind[i] = Kind::kObservation;
      t.wrong[i] = joint.factor_objects[i] < 0 || joint.factor_objects[i] != truth_of.at(f.b());
    }
    if (!t.wrong[i]) t.right.push_back(f);
  }
  return t;
}

// Precision and recall of the rejections (weight < 0.5) among the robust factors of kind `k`,
// and how many of them are wrong.
void ScoreRejections(const FactorTruth& t, FactorTruth::Kind k, const std::vector<double>& weights,
                     double* count, double* precision, double* recall) {
  int flagged = 0, flagged_wrong = 0, wrong_count = 0;
  for (std::size_t i = 0; i < t.kind.size(); ++i) {
    if (!t.robust[i] || t.kind[i] != k) continue;
    wrong_count += t.wrong[i] ? 1 : 0;
    if (weights[i] < 0.5) {
      ++flagged;
      flagged_wrong += t.wrong[i] ? 1 : 0;
    }
  }
  *count = wrong_count;
  *precision = flagged > 0 ? static_cast<double>(flagged_wrong) / flagged : 1.0;
  *recall = wrong_count > 0 ? static_cast<double>(flagged_wrong) / wrong_count : 1.0;
}

// The outlier-free solve, centralized from the same start as the robots'; empty when only wrong
// pairs linked some robot (no outlier-free reference for this run).
Values OutlierFreeSolve(const JointProblem& joint, std::vector<RelativePoseFactor> right) {
  PoseGraph free_graph(std::move(right));
  Values free = joint.initial;
  try {
    // Landmarks only wrong observations saw are not in it: they keep their initial estimate.
    for (const auto& [k, x] :
         Optimize(free_graph, CentralizedTwoStage(free_graph, joint.initial).values).values) {
      free[k] = x;
    }
  } catch (const UnderdeterminedError&) {
    free.clear();
  }
  return free;
}

// The robust solve's columns of one run (config.robust): the robust DGS, the least-squares DGS and
// the outlier-free centralized solve against the ground truth and one another, and the
// precision and recall of the rejections of each kind of robust factor.
void RobustMetrics(const ExperimentConfig& config, unsigned seed, const JointProblem& joint,
                   const MultiRobotSlamResult& slam, const Values& truth, RunMetrics& m) {
  using Kind = FactorTruth::Kind;
  FactorTruth t = ClassifyFactors(joint, slam);
  m.injected = slam.injected;
  RobustDgsOptions options;
  options.dgs.coarse_correction = config.two_level_dgs;
  options.dgs.pose_solver = DgsOptions::PoseSolver::kConjugateGradient;
  options.gnc.threshold = config.gnc_threshold;
  options.retest_left_out = config.retest_left_out;
  options.retest_groups = config.retest_groups;
  options.one_to_one_after_gnc = config.one_to_one_after_gnc;
  RobustDgsResult r;
  try {
    r = RunRobustDgs(joint.graph, joint.initial, t.robust, options);
  } catch (const UnderdeterminedError& e) {
    // The separator check refused every link of a robot: unlinked for the robust solve.
    throw UnlinkedRobotError(fmt::format("experiment {} with {} robots, seed {}: {}",
                                         config.scenario, config.robots, seed, e.what()));
  }
  ScoreRejections(t, Kind::kSeparator, r.weights, &m.wrong_factors, &m.outlier_precision,
                  &m.outlier_recall);
  ScoreRejections(t, Kind::kObservation, r.weights, &m.wrong_observations, &m.observation_precision,
                  &m.observation_recall);
  ScoreRejections(t, Kind::kLoopClosure, r.weights, &m.wrong_loop_closure_factors,
                  &m.loop_closure_precision, &m.loop_closure_recall);
  m.robust_bytes = static_cast<double>(r.bytes());
  m.robust_extra_bytes =
      static_cast<double>(r.weight_bytes + r.control_bytes + r.consistency_bytes);
  m.robust_rounds = r.iterations;
  // The least-squares DGS, refined (the same solver with every weight 1).
  DgsOptions ls_options = options.dgs;
  ls_options.refine = true;
  const Values ls = RunDgs(joint.graph, joint.initial, ls_options).values;
  const Values free = OutlierFreeSolve(joint, std::move(t.right));
  const GroundTruthErrors ls_gt = CompareToGroundTruthOrNan(ls, truth);
  const GroundTruthErrors robust_gt = CompareToGroundTruthOrNan(r.values, truth);
  m.ls_ate_poses = ls_gt.aligned.poses.ate;
  m.ls_are_poses = ls_gt.aligned.poses.are_deg;
  m.robust_ate_poses = robust_gt.aligned.poses.ate;
  m.robust_are_poses = robust_gt.aligned.poses.are_deg;
  const TrajectoryErrors vs_ls = CompareEstimates(r.values, ls);  // same gauge, no alignment
  m.robust_vs_ls_ate = vs_ls.poses.ate;
  m.robust_vs_ls_are = vs_ls.poses.are_deg;
  if (!free.empty()) {
    const GroundTruthErrors free_gt = CompareToGroundTruthOrNan(free, truth);
    m.free_ate_poses = free_gt.aligned.poses.ate;
    m.free_are_poses = free_gt.aligned.poses.are_deg;
    const TrajectoryErrors d = CompareEstimates(r.values, free);
    m.robust_vs_free_ate = d.poses.ate;
    m.robust_vs_free_are = d.poses.are_deg;
  } else {
    m.free_ate_poses = m.free_are_poses = std::nan("");
    m.robust_vs_free_ate = m.robust_vs_free_are = std::nan("");
  }
}

// Table 3's columns, per robot: the memory and the rendezvous traffic of point clouds against
// objects (the paper's formula and the bytes measured).
void MemoryAndCommunication(const ExperimentConfig& config, const MultiRobotSlamResult& slam,
                            RunMetrics& m) {
  const PointCloudModel& pc = config.point_cloud;
  const double kc = pc.points_per_frame * pc.bytes_per_point;
  std::vector<double> sent(static_cast<std::size_t>(config.robots), 0.0);
  std::vector<double> meetings(static_cast<std::size_t>(config.robots), 0.0);
  for (const RendezvousRecord& r : slam.rendezvous) {
    sent[static_cast<std::size_t>(r.event.alpha)] += static_cast<double>(r.bytes_alpha_to_beta);
    sent[static_cast<std::size_t>(r.event.beta)] += static_cast<double>(r.bytes_beta_to_alpha);
    meetings[static_cast<std::size_t>(r.event.alpha)] += 1.0;
    meetings[static_cast<std::size_t>(r.event.beta)] += 1.0;
  }
  const double n = config.robots;
  for (std::size_t r = 0; r < slam.robots.size(); ++r) {
    const ObjectSlam& robot = slam.robots[r];
    const double objects = static_cast<double>(robot.landmarks().size());
    m.memory_pcd += robot.numPoses() * kc / n;
    m.memory_obj_formula += objects * pc.points_per_object * pc.bytes_per_point / n;
    m.memory_obj_measured +=
        static_cast<double>(EncodeObjectMap(MakeObjectMapMessage(robot)).size()) / n;
    m.comm_pcd += meetings[r] * kc / n;
    m.comm_obj_formula += objects * pc.bytes_per_object / n;
    m.comm_obj_measured += sent[r] / n;
  }
}

// What the robots' SLAM and rendezvous did: measurements per pose, the joint graph's size, the
// association's precision and recall, the alignments (unknown initial poses).
void SlamMetrics(const SimulationData& data, const MultiRobotSlamResult& slam,
                 const JointProblem& joint, RunMetrics& m) {
  m.seconds_slam = slam.seconds;
  const MeasurementCoverage coverage = CoverageOf(data.measurements);
  m.measurements_per_pose = coverage.perPose();
  m.poses_without_measurement = coverage.fractionWithout();
  m.longest_without_measurement = coverage.longest_without;
  m.poses = joint.num_poses;
  m.landmarks = joint.num_landmarks;
  m.shared_objects = joint.num_object_object;
  m.rendezvous = static_cast<double>(slam.rendezvous.size());
  m.intra_precision = slam.intra.precision();
  m.intra_recall = slam.intra.recall();
  m.intra_discarded = slam.intra.discarded;
  m.intra_refused = slam.intra.refused;
  m.intra_loop_closures = slam.intra.loop_closures;
  m.intra_wrong_loop_closures = slam.intra.wrong_loop_closures;
  m.inter_precision = slam.inter.precision();
  m.inter_recall = slam.inter.recall();
  m.rendezvous_bytes = static_cast<double>(slam.bytes);
  for (const RendezvousRecord& r : slam.rendezvous) {
    m.shared_removed += r.removed;
    m.shared_removed_correct += r.removed_correct;
    if (!r.alignment) continue;
    const bool aligned = *r.alignment == AlignmentStatus::kAligned;
    m.aligned += aligned ? 1 : 0;
    m.refused_too_few += *r.alignment == AlignmentStatus::kTooFew ? 1 : 0;
    m.refused_ambiguous += *r.alignment == AlignmentStatus::kAmbiguous ? 1 : 0;
    m.refused_contradicted += *r.alignment == AlignmentStatus::kContradicted ? 1 : 0;
    m.alignments_wrong += r.alignment_wrong ? 1 : 0;
    if (r.truly_shared >= 4) {
      m.alignable += 1;
      m.alignable_aligned += aligned ? 1 : 0;
    }
  }
}

// The centralized solve (two-stage initialisation, then Gauss-Newton), and the cost from the
// chordal initialisation alone.
OptimizerResult CentralizedMetrics(const JointProblem& joint, RunMetrics& m) {
  const auto t_gn = Clock::now();
  const OptimizerResult gn =
      Optimize(joint.graph, CentralizedTwoStage(joint.graph, joint.initial).values);
  m.seconds_gn = SecondsSince(t_gn);
  m.gn_cost = gn.final_cost;
  m.gn_iterations = gn.iterations;
  m.gn_chordal_cost = Optimize(joint.graph, ChordalInitialization(joint.graph)).final_cost;
  return gn;
}

// DGS at the paper's two thresholds (the second with the refinement when config.refine), and the
// sweeps of the other DGS level for comparison. Returns the run at eta = 0.1.
DgsRun DistributedMetrics(const ExperimentConfig& config, const JointProblem& joint,
                          RunMetrics& m) {
  const bool two_level = config.two_level_dgs;
  DgsRun eta1 = RunDgsStages(joint.graph, joint.initial, 1e-1, false, two_level);
  const DgsRun eta2 = RunDgsStages(joint.graph, joint.initial, 1e-2, config.refine, two_level);
  m.iterations_eta1_other =
      RunDgsStages(joint.graph, joint.initial, 1e-1, false, !two_level).iterations;
  m.iterations_eta2_other =
      RunDgsStages(joint.graph, joint.initial, 1e-2, false, !two_level).iterations;
  m.iterations_eta1 = eta1.iterations;
  m.cost_eta1 = joint.graph.cost(eta1.values);
  m.dgs_bytes_eta1 = eta1.bytes;
  m.seconds_dgs_eta1 = eta1.seconds;
  m.iterations_eta2 = eta2.iterations;
  m.cost_eta2 = joint.graph.cost(eta2.values);
  m.dgs_bytes_eta2 = eta2.bytes;
  m.refined_cost = eta2.refined_cost;
  m.refine_iterations = eta2.refine_iterations;
  m.refine_bytes = eta2.refine_bytes;
  m.seconds_refine = eta2.refine_seconds;
  return eta1;
}

// DGS against the centralized estimate (ATE* / ARE*), and both against ground truth.
void AccuracyMetrics(const Values& gn, const Values& dgs, const Values& truth, RunMetrics& m) {
  const TrajectoryErrors star = CompareEstimates(dgs, gn);
  m.ate_star_poses = star.poses.ate;
  m.ate_star_landmarks = star.objects.ate;
  m.are_star_poses = star.poses.are_deg;
  m.are_star_landmarks = star.objects.are_deg;
  const GroundTruthErrors gn_gt = CompareToGroundTruthOrNan(gn, truth);
  const GroundTruthErrors dgs_gt = CompareToGroundTruthOrNan(dgs, truth);
  m.gn_ate_poses = gn_gt.aligned.poses.ate;
  m.gn_ate_landmarks = gn_gt.aligned.objects.ate;
  m.gn_are_poses = gn_gt.aligned.poses.are_deg;
  m.gn_are_landmarks = gn_gt.aligned.objects.are_deg;
  m.dgs_ate_poses = dgs_gt.aligned.poses.ate;
  m.dgs_ate_landmarks = dgs_gt.aligned.objects.ate;
  m.dgs_are_poses = dgs_gt.aligned.poses.are_deg;
  m.dgs_are_landmarks = dgs_gt.aligned.objects.are_deg;
}

// The columns of a table of `kind` after scenario, robots and noise; `other`: the DGS variant run
// beside the tables' one, for its sweep counts.
std::vector<std::string> TableColumns(TableKind kind, const std::string& other) {
  switch (kind) {
    case TableKind::kAccuracy:
      return {"#Iter η=1e-1",
              "Cost η=1e-1",
              "#Iter η=1e-2",
              "Cost η=1e-2",
              "GN cost",
              "Refined cost",
              "ATE* poses (m)",
              "ATE* lmks (m)",
              "ARE* poses (deg)",
              "ARE* lmks (deg)",
              other + " #Iter η=1e-1 / 1e-2"};
    case TableKind::kAssociation:
      return {"Intra precision",         "Intra recall",
              "Rendezvous precision",    "Rendezvous recall",
              "Shared objects",          "GT ATE poses GN/DGS (m)",
              "GT ATE lmks GN/DGS (m)",  "GT ARE poses GN/DGS (deg)",
              "GT ARE lmks GN/DGS (deg)"};
    case TableKind::kMemory:
      return {"Frames",          "Objects",         "Rendezvous",
              "Memory PCD (MB)", "Memory Obj (MB)", "Memory Obj measured (MB)",
              "Comm. PCD (MB)",  "Comm. Obj (MB)",  "Comm. Obj measured (MB)",
              "DGS traffic (MB)"};
    case TableKind::kScale:
      return {"Poses",
              "Landmarks",
              "#Iter η=1e-1",
              "#Iter η=1e-2",
              other + " #Iter η=1e-1 / 1e-2",
              "Cost η=1e-1 / GN",
              "Cost η=1e-2 / GN",
              "Refined / GN",
              "Rendezvous bytes",
              "DGS bytes η=1e-1",
              "Refine bytes",
              "Time SLAM / GN / DGS / refine (s)",
              "Time total (s)"};
    case TableKind::kPerception:
      return {"Frames",
              "Detections",
              "True detections",
              "Accepted (true)",
              "Accepted of true, objects >= 30 % visible",
              "Rejected by the 12-inlier gate (false det.)",
              "Median pose error (cm / deg)",
              "ms/frame render / detect / segment / register",
              "Point clouds of the frames (MB/robot)",
              "Object map measured (MB/robot)",
              "GN cost",
              "Refined cost",
              "ATE* poses (m)"};
    case TableKind::kRobust:
      return {"Initial poses",
              "P",
              "Runs (skipped)",
              "Rendezvous precision / recall",
              "Aligned / refused few / ambiguous / contradicted / wrong",
              "Aligned of alignable",
              "Wrong factors (injected)",
              "Outlier precision / recall",
              "Wrong observations",
              "Observation outliers precision / recall",
              "GT ATE poses LS / robust / free (m)",
              "GT ARE poses LS / robust / free (deg)",
              "Robust vs free, worst run: ATE (m) / ARE (deg)",
              "Robust extra bytes"};
  }
  return {};
}

// The robust table's cells: alignment and association, then what the robust solve measured
// ("-" when it did not run).
std::vector<std::string> RobustCells(const ExperimentResult& r) {
  const RunMetrics& m = r.mean;
  const ExperimentConfig& c = r.config;
  double worst_ate = 0.0, worst_are = 0.0;
  for (const RunMetrics& run : r.runs) {
    worst_ate = std::max(worst_ate, run.robust_vs_free_ate);
    worst_are = std::max(worst_are, run.robust_vs_free_are);
  }
  const bool unknown = !c.known_initial_poses;
  std::vector<std::string> extra = {
      unknown ? "unknown" : "known",
      Fix(c.outlier_fraction, 1),
      fmt::format("{} ({})", r.runs.size(), r.skipped.size()),
      Fix(m.inter_precision, 3) + " / " + Fix(m.inter_recall, 3),
      unknown ? fmt::format("{} / {} / {} / {} / {}", Fix(m.aligned), Fix(m.refused_too_few),
                            Fix(m.refused_ambiguous), Fix(m.refused_contradicted),
                            Fix(m.alignments_wrong))
              : "-",
      unknown && m.alignable > 0 ? Fix(100.0 * m.alignable_aligned / m.alignable, 1) + " %" : "-"};
  // What the robust solve measures: "-" when it did not run.
  const std::vector<std::string> solved = {
      Fix(m.wrong_factors) + " (" + Fix(m.injected) + ")",
      Fix(m.outlier_precision, 3) + " / " + Fix(m.outlier_recall, 3),
      Fix(m.wrong_observations),
      Fix(m.observation_precision, 3) + " / " + Fix(m.observation_recall, 3),
      Sci(m.ls_ate_poses) + " / " + Sci(m.robust_ate_poses) + " / " + Sci(m.free_ate_poses),
      Sci(m.ls_are_poses) + " / " + Sci(m.robust_are_poses) + " / " + Sci(m.free_are_poses),
      Sci(worst_ate) + " / " + Sci(worst_are),
      Sci(m.robust_extra_bytes)};
  for (const std::string& cell : solved) extra.push_back(c.robust ? cell : "-");
  return extra;
}

// The cells of one row of a table of `kind` after scenario, robots and noise.
std::vector<std::string> TableCells(TableKind kind, const ExperimentResult& r) {
  const RunMetrics& m = r.mean;
  const ExperimentConfig& c = r.config;
  const double robots = c.robots;
  switch (kind) {
    case TableKind::kAccuracy:
      return {Fix(m.iterations_eta1),
              Fix(m.cost_eta1),
              Fix(m.iterations_eta2),
              Fix(m.cost_eta2),
              Fix(m.gn_cost),
              Fix(m.refined_cost),
              Sci(m.ate_star_poses),
              Sci(m.ate_star_landmarks),
              Sci(m.are_star_poses),
              Sci(m.are_star_landmarks),
              Fix(m.iterations_eta1_other) + " / " + Fix(m.iterations_eta2_other)};
    case TableKind::kAssociation:
      return {Fix(m.intra_precision, 3),
              Fix(m.intra_recall, 3),
              Fix(m.inter_precision, 3),
              Fix(m.inter_recall, 3),
              Fix(m.shared_objects),
              Sci(m.gn_ate_poses) + " / " + Sci(m.dgs_ate_poses),
              Sci(m.gn_ate_landmarks) + " / " + Sci(m.dgs_ate_landmarks),
              Sci(m.gn_are_poses) + " / " + Sci(m.dgs_are_poses),
              Sci(m.gn_are_landmarks) + " / " + Sci(m.dgs_are_landmarks)};
    case TableKind::kMemory:
      return {Fix(m.poses / robots),   Fix(m.landmarks / robots), Fix(2.0 * m.rendezvous / robots),
              MB(m.memory_pcd),        MB(m.memory_obj_formula),  MB(m.memory_obj_measured),
              MB(m.comm_pcd),          MB(m.comm_obj_formula),    MB(m.comm_obj_measured),
              MB(m.comm_dgs_per_robot)};
    case TableKind::kScale:
      return {Fix(m.poses, 0),
              Fix(m.landmarks, 0),
              Fix(m.iterations_eta1),
              Fix(m.iterations_eta2),
              Fix(m.iterations_eta1_other) + " / " + Fix(m.iterations_eta2_other),
              Fix(m.cost_eta1 / m.gn_cost, 4),
              Fix(m.cost_eta2 / m.gn_cost, 4),
              Fix(m.refined_cost / m.gn_cost, 6),
              Sci(m.rendezvous_bytes),
              Sci(m.dgs_bytes_eta1),
              Sci(m.refine_bytes),
              fmt::format("{} / {} / {} / {}", Fix(m.seconds_slam, 2), Fix(m.seconds_gn, 2),
                          Fix(m.seconds_dgs_eta1, 2), Fix(m.seconds_refine, 2)),
              Fix(m.seconds, 2)};
    case TableKind::kPerception:
      return {Fix(m.perception_frames),
              Fix(m.perception_detections),
              Fix(m.perception_true_detections),
              Fix(m.perception_accepted) + " (" + Fix(m.perception_accepted_true) + ")",
              Fix(m.perception_accepted_visible) + " of " + Fix(m.perception_true_visible) + " (" +
                  Fix(100.0 * m.perception_accepted_visible / m.perception_true_visible, 1) + " %)",
              Fix(m.perception_rejected_inliers) + " (" + Fix(m.perception_rejected_inliers_false) +
                  ")",
              Fix(100.0 * m.perception_median_error_m, 1) + " / " +
                  Fix(m.perception_median_error_deg, 1),
              fmt::format("{} / {} / {} / {}", Fix(m.perception_ms_render, 0),
                          Fix(m.perception_ms_detect, 0), Fix(m.perception_ms_segment, 0),
                          Fix(m.perception_ms_register, 0)),
              MB(m.perception_pcd_bytes),
              MB(m.memory_obj_measured),
              Fix(m.gn_cost),
              Fix(m.refined_cost),
              Sci(m.ate_star_poses)};
    case TableKind::kRobust:
      return RobustCells(r);
  }
  return {};
}

}  // namespace

std::string ToString(InformationMode mode) {
  return mode == InformationMode::kFixed ? "fixed" : "noise";
}

InformationMode InformationModeFromString(const std::string& text) {
  if (text == "noise") return InformationMode::kNoise;
  if (text == "fixed") return InformationMode::kFixed;
  throw InvalidInputError("information mode must be 'noise' or 'fixed', got '" + text + "'");
}

TableKind TableKindFromString(const std::string& text) {
  if (text == "accuracy") return TableKind::kAccuracy;
  if (text == "association") return TableKind::kAssociation;
  if (text == "memory") return TableKind::kMemory;
  if (text == "scale") return TableKind::kScale;
  if (text == "perception") return TableKind::kPerception;
  if (text == "robust") return TableKind::kRobust;
  throw InvalidInputError(
      "table must be accuracy, association, memory, scale, perception or robust, got '" + text +
      "'");
}

void ExperimentConfig::validate() const {
  if (scenario != "chairs25" && scenario != "house" && scenario != "generated") {
    throw InvalidInputError("experiment: scenario must be chairs25, house or generated, got '" +
                            scenario + "'");
  }
  if (robots < 1) {
    throw InvalidInputError("experiment: robots must be at least 1, got " + std::to_string(robots));
  }
  if (runs < 1) {
    throw InvalidInputError("experiment: runs must be at least 1, got " + std::to_string(runs));
  }
  if (seed > std::numeric_limits<unsigned>::max() - static_cast<unsigned>(runs - 1)) {
    throw InvalidInputError(
        fmt::format("experiment: the runs' seeds, seed {} .. seed + {}, pass the largest seed {}",
                    seed, runs - 1, std::numeric_limits<unsigned>::max()));
  }
  if (!(sigma_rotation_deg >= 0.0) || !std::isfinite(sigma_rotation_deg)) {
    throw InvalidInputError("experiment: sigma_rotation_deg must be finite and >= 0");
  }
  if (!(sigma_translation >= 0.0) || !std::isfinite(sigma_translation)) {
    throw InvalidInputError("experiment: sigma_translation must be finite and >= 0");
  }
  if (!(outlier_fraction >= 0.0 && outlier_fraction < 1.0)) {
    throw InvalidInputError("experiment: outlier_fraction must be in [0, 1)");
  }
  if (!(gnc_threshold >= 0.0) || !std::isfinite(gnc_threshold)) {
    throw InvalidInputError("experiment: gnc_threshold must be finite and >= 0");
  }
  if (!(exclusion_radius >= 0.0) || !std::isfinite(exclusion_radius)) {
    throw InvalidInputError("experiment: exclusion_radius must be finite and >= 0");
  }
  if (!(ambiguity_ratio >= 0.0 && ambiguity_ratio < 1.0)) {
    throw InvalidInputError("experiment: ambiguity_ratio must be in [0, 1) (0: off)");
  }
  if (!(covariance_gate >= 0.0) || !std::isfinite(covariance_gate)) {
    throw InvalidInputError("experiment: covariance_gate must be finite and >= 0 (0: off)");
  }
  if (poses_per_robot < 2) {
    throw InvalidInputError("experiment: poses_per_robot must be at least 2, got " +
                            std::to_string(poses_per_robot));
  }
  const PointCloudModel& p = point_cloud;
  for (double v :
       {p.points_per_frame, p.bytes_per_point, p.points_per_object, p.bytes_per_object}) {
    if (!(v > 0.0) || !std::isfinite(v)) {
      throw InvalidInputError("experiment: point-cloud model values must be positive");
    }
  }
}

SimulatedRun SimulateRun(const ExperimentConfig& config, int run, RunMetrics& metrics) {
  config.validate();
  SimulatedRun out;
  out.seed = config.seed + static_cast<unsigned>(run);
  const World world = MakeScenarioWorld(config.scenario, out.seed, config.robots);
  const SimulationConfig sim =
      NoiseSimulationConfig(config.robots, config.poses_per_robot, out.seed,
                            config.sigma_rotation_deg, config.sigma_translation);
  out.data = Simulate(world, sim);
  if (config.perceive) config.perceive(out.data, metrics);
  out.slam = MultiRobotSlamConfigForNoise(sim.sensing);
  out.slam.known_initial_poses = config.known_initial_poses;
  out.slam.slam.exclusion_radius = config.exclusion_radius;
  out.slam.slam.leave_one_out_check = config.leave_one_out_check;
  out.slam.slam.ambiguity_ratio = config.ambiguity_ratio;
  out.slam.slam.covariance_gate = config.covariance_gate;
  out.slam.slam.loop_closure = config.loop_closure;
  out.slam.rendezvous.refine_by_constellation = config.rendezvous_constellation;
  out.slam.outlier_fraction = config.outlier_fraction;
  out.slam.outlier_seed = out.seed;
  return out;
}

std::map<Key, int> LandmarkObjects(const JointProblem& joint,
                                   const std::vector<ObjectSlam>& robots) {
  std::map<Key, std::map<int, int>> seen;
  for (std::size_t i = 0; i < joint.graph.factors().size(); ++i) {
    if (joint.factor_objects[i] != ObjectSlam::kNoObservation) {
      ++seen[joint.graph.factors()[i].b()][joint.factor_objects[i]];
    }
  }
  std::map<Key, int> truth_of;
  for (const ObjectSlam& robot : robots) {
    for (const Landmark& l : robot.landmarks()) {
      int best = l.true_object, most = seen[l.key][l.true_object];
      for (const auto& [object, count] : seen[l.key]) {
        if (count > most) best = object, most = count;
      }
      truth_of[l.key] = best;
    }
  }
  return truth_of;
}

bool WrongPair(const std::map<Key, int>& objects, const Key& a, const Key& b) {
  const int ta = objects.at(a), tb = objects.at(b);
  return ta < 0 || ta != tb;
}

RunMetrics RunSimulationOnce(const ExperimentConfig& config, int run, RunEstimates* estimates) {
  const auto t0 = Clock::now();
  RunMetrics m;
  SimulatedRun simulated = SimulateRun(config, run, m);
  const unsigned seed = simulated.seed;
  const SimulationData& data = simulated.data;
  const MultiRobotSlamConfig& slam_config = simulated.slam;
  const MultiRobotSlamResult slam = RunMultiRobotObjectSlam(data, slam_config);
  JointProblem joint =
      AssembleJointProblem(slam.robots, slam.shared, slam_config.rendezvous.lambda());
  if (!joint.unanchored_robots.empty()) {
    throw UnlinkedRobotError(fmt::format(
        "experiment {} with {} robots, seed {}: robot {} never linked to robot 0 through "
        "rendezvous (try another seed or more poses per robot)",
        config.scenario, config.robots, seed, joint.unanchored_robots.front()));
  }
  if (config.information == InformationMode::kFixed) {
    NoiseModel paper;  // 5 deg, 0.2 m
    joint.graph =
        WithInformation(joint.graph, paper.information(SensingConfig().information_sigma_floor));
  }
  SlamMetrics(data, slam, joint, m);
  const OptimizerResult gn = CentralizedMetrics(joint, m);
  const DgsRun eta1 = DistributedMetrics(config, joint, m);
  const Values truth = JointGroundTruth(data, slam.robots);
  AccuracyMetrics(gn.values, eta1.values, truth, m);
  if (config.robust) RobustMetrics(config, seed, joint, slam, truth, m);

  MemoryAndCommunication(config, slam, m);
  m.comm_dgs_per_robot = m.dgs_bytes_eta1 / config.robots;
  m.seconds = SecondsSince(t0);

  if (estimates != nullptr) {
    estimates->ground_truth = truth;
    estimates->centralized = gn.values;
    estimates->dgs = eta1.values;
    estimates->robots = config.robots;
  }
  return m;
}

RunMetrics MeanOf(const std::vector<RunMetrics>& runs) {
  RunMetrics mean;
  if (runs.empty()) return mean;
  for (const auto& [name, field] : Fields()) {
    double sum = 0.0;
    for (const RunMetrics& r : runs) sum += r.*field;
    mean.*field = sum / static_cast<double>(runs.size());
  }
  return mean;
}

ExperimentResult RunExperiment(const ExperimentConfig& config, RunEstimates* first_estimates) {
  config.validate();
  ExperimentResult result;
  result.config = config;
  for (int i = 0; i < config.runs; ++i) {
    try {
      result.runs.push_back(RunSimulationOnce(config, i, i == 0 ? first_estimates : nullptr));
    } catch (const UnlinkedRobotError&) {
      if (!config.skip_unlinked) throw;
      result.skipped.push_back(i);
    }
  }
  if (result.runs.empty()) {
    throw UnderdeterminedError(fmt::format("experiment {} with {} robots: every run left a robot "
                                           "unlinked",
                                           config.scenario, config.robots));
  }
  result.mean = MeanOf(result.runs);
  return result;
}

std::string FormatMarkdownTable(const std::vector<ExperimentResult>& results, TableKind kind) {
  std::string out;
  auto row = [&out](const std::vector<std::string>& cells) {
    out += "|";
    for (const auto& c : cells) out += " " + c + " |";
    out += "\n";
  };
  auto rule = [&out](std::size_t columns) {
    out += "|";
    for (std::size_t i = 0; i < columns; ++i) out += "---|";
    out += "\n";
  };
  std::vector<std::string> head = {"Scenario", "Robots", "σR (deg)", "σt (m)"};
  const bool two_level = results.empty() || results.front().config.two_level_dgs;
  const std::vector<std::string> extra = TableColumns(kind, two_level ? "One-level" : "Two-level");
  head.insert(head.end(), extra.begin(), extra.end());
  row(head);
  rule(head.size());
  for (const ExperimentResult& r : results) {
    const ExperimentConfig& c = r.config;
    std::vector<std::string> cells = {c.scenario, std::to_string(c.robots),
                                      Fix(c.sigma_rotation_deg, 0), Fix(c.sigma_translation, 2)};
    const std::vector<std::string> more = TableCells(kind, r);
    cells.insert(cells.end(), more.begin(), more.end());
    row(cells);
  }
  return out;
}

std::string ResultsToJson(const std::vector<ExperimentResult>& results) {
  auto metrics = [](const RunMetrics& m) {
    nlohmann::json j = nlohmann::json::object();
    for (const auto& [name, field] : Fields()) {
      const double v = m.*field;
      j[name] = std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr);
    }
    return j;
  };
  nlohmann::json rows = nlohmann::json::array();
  for (const ExperimentResult& r : results) {
    const ExperimentConfig& c = r.config;
    nlohmann::json config = {{"scenario", c.scenario},
                             {"robots", c.robots},
                             {"runs", c.runs},
                             {"seed", c.seed},
                             {"sigma_rotation_deg", c.sigma_rotation_deg},
                             {"sigma_translation", c.sigma_translation},
                             {"information", ToString(c.information)},
                             {"poses_per_robot", c.poses_per_robot},
                             {"refine", c.refine},
                             {"dgs", c.two_level_dgs ? "two-level" : "one-level"},
                             {"perception", c.perceive ? c.perception : "sampled"},
                             {"points_per_frame", c.point_cloud.points_per_frame},
                             {"bytes_per_point", c.point_cloud.bytes_per_point},
                             {"points_per_object", c.point_cloud.points_per_object},
                             {"bytes_per_object", c.point_cloud.bytes_per_object},
                             {"initial_poses", c.known_initial_poses ? "known" : "unknown"},
                             {"outlier_fraction", c.outlier_fraction},
                             {"robust", c.robust},
                             {"exclusion_radius", c.exclusion_radius},
                             {"leave_one_out_check", c.leave_one_out_check},
                             {"ambiguity_ratio", c.ambiguity_ratio},
                             {"covariance_gate", c.covariance_gate},
                             {"loop_closure", c.loop_closure},
                             {"rendezvous_constellation", c.rendezvous_constellation},
                             {"skipped_runs", r.skipped}};
    nlohmann::json runs = nlohmann::json::array();
    for (const RunMetrics& m : r.runs) runs.push_back(metrics(m));
    rows.push_back({{"config", config}, {"mean", metrics(r.mean)}, {"runs", runs}});
  }
  return nlohmann::json{{"rows", rows}}.dump();
}

std::string PlotSvg(const RunEstimates& e, const std::string& title) {
  double min_x = std::numeric_limits<double>::infinity(), min_y = min_x;
  double max_x = -min_x, max_y = -min_x;
  for (const Values* v : {&e.centralized, &e.dgs}) {
    for (const auto& [key, pose] : *v) {
      const Vector3 t = pose.translation();
      min_x = std::min(min_x, t.x());
      max_x = std::max(max_x, t.x());
      min_y = std::min(min_y, t.y());
      max_y = std::max(max_y, t.y());
    }
  }
  if (!std::isfinite(min_x)) {
    min_x = min_y = 0.0;
    max_x = max_y = 1.0;
  }
  const double margin = 40.0, width = 800.0;
  const double span = std::max({max_x - min_x, max_y - min_y, 1e-6});
  const double scale = (width - 2 * margin) / span;
  const double height = (max_y - min_y) * scale + 2 * margin + 30.0;
  auto px = [&](const Vector3& t) {
    return fmt::format("{:.2f},{:.2f}", margin + (t.x() - min_x) * scale,
                       height - margin - (t.y() - min_y) * scale);
  };
  static const char* kColours[] = {"#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd",
                                   "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22", "#17becf"};
  std::string svg = fmt::format(
      "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<svg xmlns=\"http://www.w3.org/2000/svg\" "
      "width=\"{:.0f}\" height=\"{:.0f}\" viewBox=\"0 0 {:.0f} {:.0f}\">\n"
      "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n"
      "<text x=\"{:.0f}\" y=\"20\" font-family=\"sans-serif\" font-size=\"14\">{}</text>\n"
      "<text x=\"{:.0f}\" y=\"36\" font-family=\"sans-serif\" font-size=\"11\">solid / filled: "
      "centralized GN; dashed / open: DGS (eta 1e-1); one colour per robot; {:.1f} m across"
      "</text>\n",
      width, height, width, height, margin, title, margin, span);
  for (int r = 0; r < e.robots; ++r) {
    const char* colour = kColours[r % 10];
    for (int pass = 0; pass < 2; ++pass) {
      const Values& v = pass == 0 ? e.centralized : e.dgs;
      std::string points;
      for (const auto& [key, pose] : v) {
        if (key.robot == r && key.isPose()) points += px(pose.translation()) + " ";
      }
      if (!points.empty()) points.pop_back();
      svg += fmt::format(
          "<polyline fill=\"none\" stroke=\"{}\" stroke-width=\"{}\"{} points=\"{}\"/>\n", colour,
          pass == 0 ? "2" : "1.5", pass == 0 ? "" : " stroke-dasharray=\"6,4\" stroke-opacity=\"0.8\"",
          points);
      for (const auto& [key, pose] : v) {
        if (key.robot != r || !key.isObject()) continue;
        const std::string p = px(pose.translation());
        const auto comma = p.find(',');
        svg += fmt::format(
            "<circle cx=\"{}\" cy=\"{}\" r=\"{}\" fill=\"{}\" stroke=\"{}\" stroke-width=\"1.5\"/>\n",
            p.substr(0, comma), p.substr(comma + 1), pass == 0 ? "3.5" : "6",
            pass == 0 ? colour : "none", colour);
      }
    }
  }
  svg += "</svg>\n";
  return svg;
}

}  // namespace moslam
