// Seeded synthetic pose graphs with known ground truth, for tests and examples: robots drive
// noisy odometry along a grid-like path with loop closures between nearby poses.
#pragma once

#include "moslam/graph/pose_graph.h"

namespace moslam {

struct SyntheticGraphOptions {
  int num_robots = 1;
  int poses_per_robot = 50;
  double sigma_rotation = 0.0;     // rad, per axis, added to every measurement
  double sigma_translation = 0.0;  // m, per axis
  double loop_closure_radius = 1.5;  // m: poses closer than this (ground truth) get an edge
  int max_loop_closures_per_pose = 2;
  unsigned seed = 1;
  // Throws InvalidInputError naming the first bad field.
  void validate() const;
};

struct SyntheticGraph {
  PoseGraph graph;
  Values ground_truth;
};

// Information matrices are diag(1/sigma^2) (with a floor so noise-free graphs stay SPD).
// Throws InvalidInputError on out-of-range options (validate()).
SyntheticGraph MakeSyntheticGraph(const SyntheticGraphOptions& options);

}  // namespace moslam
