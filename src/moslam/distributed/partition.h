// Splitting a pose graph among robots for the distributed solver.
//
// PartitionByRobot: ownership is the robot in each key (distributed-mapper folders, object
// datasets). Robot r's subgraph holds every factor with an end owned by r, so a separator
// (ends owned by two robots) is in both robots' subgraphs, and every prior on r's variables.
//
// SplitIntoRobots: a single-robot dataset (all variables poses of robot 0) split into N robots
// by contiguous blocks of pose indices (sizes differ by at most one); block b becomes robot b,
// keeping the pose indices. The first pose stays robot 0's first pose, so the gauge is the same.
#pragma once

#include <map>
#include <vector>

#include "moslam/graph/pose_graph.h"

namespace moslam {

struct RobotSubgraph {
  int robot = 0;
  PoseGraph graph;
};

// One entry per robot that owns at least one variable, by increasing robot id.
std::vector<RobotSubgraph> PartitionByRobot(const PoseGraph& graph);

struct SplitGraph {
  PoseGraph graph;
  Values initial;                  // the input's initial values, re-keyed (missing stay missing)
  std::map<Key, Key> original_key; // new key -> key in the input
};

// Throws InvalidInputError when num_robots < 1, exceeds the number of poses, or the graph has a
// variable that is not a pose of robot 0.
SplitGraph SplitIntoRobots(const PoseGraph& graph, const Values& initial, int num_robots);

// Re-keys an estimate of the split graph back to the input's keys. Throws InvalidInputError on a
// key the map does not know.
Values RestoreOriginalKeys(const Values& values, const std::map<Key, Key>& original_key);

}  // namespace moslam
