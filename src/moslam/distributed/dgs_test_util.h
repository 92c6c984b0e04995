// Helpers shared by the distributed tests (not part of the library).
#pragma once

#include <string>

#include "moslam/distributed/centralized_two_stage.h"
#include "moslam/graph/pose_graph.h"
#include "moslam/io/g2o.h"
#include "moslam/metrics/metrics.h"

namespace moslam::test {

inline std::string BlocksWorldFolder(int robots) {
  return std::string(MOSLAM_DATASETS_DIR) +
         "/distributed-mapper/CogRob_distributed-mapper/distributed_mapper_core/data/"
         "blocks_world/" +
         std::to_string(robots) + "robots";
}

inline constexpr int kBlocksWorldRobots[] = {2, 4, 9, 16, 25, 36, 49};

// Three robots, each a chain of `n` poses along x (1 m apart, robot r starting at 10 + 10 r m),
// consecutive robots linked last pose to first pose; noise-free. Initial values: ground truth.
inline PoseGraph ChainOfRobots(int robots, int n, Values* ground_truth) {
  PoseGraph g;
  Values gt;
  auto pose = [](int r, int i) {
    return SE3(SO3::Exp(Vector3(0.0, 0.0, 0.1 * (r * 7 + i))),
               Vector3(10.0 + 10.0 * r + i, 0.3 * i, 0.0));
  };
  for (int r = 0; r < robots; ++r) {
    for (int i = 0; i < n; ++i) gt[Key::Pose(r, static_cast<std::uint64_t>(i))] = pose(r, i);
  }
  auto edge = [&](Key a, Key b) {
    g.add(RelativePoseFactor(a, b, gt.at(a).between(gt.at(b)), Matrix6::Identity()));
  };
  for (int r = 0; r < robots; ++r) {
    for (int i = 0; i + 1 < n; ++i) {
      edge(Key::Pose(r, static_cast<std::uint64_t>(i)), Key::Pose(r, static_cast<std::uint64_t>(i + 1)));
    }
    if (r + 1 < robots) edge(Key::Pose(r, static_cast<std::uint64_t>(n - 1)), Key::Pose(r + 1, 0));
  }
  if (ground_truth) *ground_truth = gt;
  return g;
}

}  // namespace moslam::test
