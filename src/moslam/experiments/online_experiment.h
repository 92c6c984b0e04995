// Online mapping over many runs (`moslam simulate --online`): the mission of the paper's
// simulation with a group solve at every rendezvous (online/online_team.h), measured as it goes.
//
// One run (RunOnlineSimulationOnce) simulates the scenario as RunSimulationOnce does (same seed,
// same data), then runs the multi-robot SLAM twice on it:
//   online  the robots in range solve their joint graph at every rendezvous (two-level DGS and
//           the refinement, OnlineOptions::solver) and continue from it;
//   solo    the batch mode: each robot's own SLAM, the shared objects only collected.
// After every group solve it measures the map error of the team: the mean over the robots of the
// ATE of each robot's own map (its poses so far, against ground truth after aligning that map
// alone: a robot's map is in its own frame), online and solo at the same step. At the end each
// robot's map is compared with the batch optimum of the same factors (the centralized solve of
// the online run's final joint graph, each robot's poses aligned alone as well).
//
// Bytes at a rendezvous: the object lists and shared pairs exchanged (measured, serialized), the
// group solve's DGS messages (measured, serialized, as the processes send them), against the
// point clouds the paper's alternative would send (PointCloudModel: one frame K x C per robot).
#pragma once

#include <string>
#include <vector>

#include "moslam/experiments/simulation_experiment.h"
#include "moslam/online/online_team.h"

namespace moslam {

struct OnlineExperimentConfig {
  // Scenario, robots, runs, seed, noise, poses per robot, initial poses known or not, the
  // point-cloud model, the robots' association options, injected wrong pairs
  // (outlier_fraction), and the robust group solves (robust, gnc_threshold, retest_left_out:
  // OnlineOptions::robust is built from them and must not be set in `online`). Perception is
  // not part of it (must be off).
  ExperimentConfig base;
  OnlineOptions online;
  // Throws InvalidInputError naming the first bad field.
  void validate() const;
};

// After one group solve.
struct OnlineRendezvousPoint {
  int step = 0;
  std::vector<int> robots;
  double team_ate = 0.0;  // m, online: mean over the robots of their map's ATE (poses, aligned)
  double solo_ate = 0.0;  // m, the same for the solo maps at this step
  int robots_measured = 0;  // robots with 3 non-collinear positions so far (the others left out)
  int rotation_sweeps = 0, pose_sweeps = 0, refine_steps = 0;
  int object_object = 0, team_factors = 0;
  double bytes_objects = 0.0;  // the rendezvous messages of this step among these robots
  double bytes_dgs = 0.0;      // the group solve's messages
  double bytes_point_clouds = 0.0;  // one frame per robot of the group (PointCloudModel)
  double seconds = 0.0;             // the group solve
};

struct OnlineRunMetrics {
  unsigned seed = 0;
  std::vector<OnlineRendezvousPoint> points;
  // Per robot at the end: ATE (m) of its map online, of the batch optimum of the same factors,
  // of its solo map; ARE (deg) online and batch.
  std::vector<double> online_ate, batch_ate, solo_ate, online_are, batch_are;
  // ATE (m) per robot of the outlier-free batch optimum: the robots' final graphs without their
  // wrong object-pose factors, with the right pairs of all that were found (LandmarkObjects: a
  // pair of two world objects is wrong); NaN when the right factors leave a robot unlinked.
  std::vector<double> free_ate;
  double worst_ratio = 0.0;  // max over robots of online_ate / batch_ate
  // Shared pairs at the end (set aside included), the wrong ones among them, the injected ones
  // (wrong by construction, counted at the rendezvous), the pairs set aside by the robust
  // solves at the end and the wrong ones among those; group solves the robust check left
  // unlinked (not solved); the robust solves' weights, GNC control and check bytes.
  double pairs = 0.0, wrong_pairs = 0.0, injected = 0.0, set_aside = 0.0, set_aside_wrong = 0.0;
  double unlinked_solves = 0.0, robust_extra_bytes = 0.0;
  // Object-pose factors at the end: wrong (the detection is of another object than its landmark
  // stands for: LandmarkObjects), set aside (the robot's weight < 0.5), and both.
  double wrong_observations = 0.0, observations_set_aside = 0.0;
  double observations_set_aside_wrong = 0.0;
  double rendezvous = 0.0, solves = 0.0;
  double bytes_objects = 0.0, bytes_dgs = 0.0;
  double seconds = 0.0;
};

struct OnlineExperimentResult {
  OnlineExperimentConfig config;
  std::vector<OnlineRunMetrics> runs;
};

// Run `run` (seed base.seed + run). Throws the errors of the modules it drives.
OnlineRunMetrics RunOnlineSimulationOnce(const OnlineExperimentConfig& config, int run);
OnlineExperimentResult RunOnlineExperiment(const OnlineExperimentConfig& config);

// A Markdown table, one row per result: runs, rendezvous and solves per run, final ATE (mean
// over robots and runs) online / batch / solo, the worst and the median per-robot ratio online /
// batch, robots within 1.1x, bytes per rendezvous (objects, DGS, point clouds).
std::string FormatOnlineTable(const std::vector<OnlineExperimentResult>& results);
// With wrong pairs (injected, or the matcher's) and the robust group solves: one row per result,
// pairs and wrong pairs per run, the pairs set aside at the end, outlier precision / recall over
// the runs (set aside and wrong / set aside, / wrong), the object-pose factors wrong, set aside
// and both, unlinked solves, final ATE online / batch
// of the pairs kept / outlier-free batch / solo, the per-robot ratio online / outlier-free
// (median, worst, within 1.1x), and the robust solves' extra bytes.
std::string FormatOnlineRobustTable(const std::vector<OnlineExperimentResult>& results);
// {"rows": [{"config": {...}, "runs": [{..., "points": [...]}, ...]}, ...]} on one line.
std::string OnlineResultsToJson(const std::vector<OnlineExperimentResult>& results);
// The team's map error after each rendezvous (x: time step, y: ATE), every run of `result`:
// online solid, solo dashed, and the mean final batch-optimum error as a horizontal line.
std::string PlotOnlineSvg(const OnlineExperimentResult& result, const std::string& title);

}  // namespace moslam
