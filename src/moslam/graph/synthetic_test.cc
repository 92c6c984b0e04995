#include "moslam/graph/synthetic.h"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <string>

#include "moslam/common/errors.h"

namespace moslam {
namespace {

TEST(SyntheticGraph, EveryRobotsPosesWithOdometryAndLoopClosures) {
  SyntheticGraphOptions o;
  o.num_robots = 3;
  o.poses_per_robot = 20;
  const SyntheticGraph s = MakeSyntheticGraph(o);
  EXPECT_EQ(s.ground_truth.size(), 60u);
  // Odometry (19 per robot) and at least one loop closure or inter-robot edge.
  EXPECT_GT(s.graph.factors().size(), 3u * 19u);
  EXPECT_EQ(MakeSyntheticGraph(o).graph.factors().size(), s.graph.factors().size());  // seeded
}

TEST(SyntheticGraph, BadOptionsNameTheField) {
  const auto refused = [](const std::function<void(SyntheticGraphOptions&)>& change,
                          const std::string& field) {
    SyntheticGraphOptions o;
    change(o);
    try {
      MakeSyntheticGraph(o);
      ADD_FAILURE() << "no exception for " << field;
    } catch (const InvalidInputError& e) {
      EXPECT_NE(std::string(e.what()).find(field), std::string::npos) << e.what();
    }
  };
  refused([](SyntheticGraphOptions& o) { o.num_robots = 0; }, "num_robots");
  refused([](SyntheticGraphOptions& o) { o.poses_per_robot = 1; }, "poses_per_robot");
  refused([](SyntheticGraphOptions& o) { o.sigma_rotation = std::nan(""); }, "sigma_rotation");
  refused([](SyntheticGraphOptions& o) { o.sigma_translation = -0.1; }, "sigma_translation");
  refused([](SyntheticGraphOptions& o) { o.loop_closure_radius = INFINITY; },
          "loop_closure_radius");
  refused([](SyntheticGraphOptions& o) { o.max_loop_closures_per_pose = -1; },
          "max_loop_closures_per_pose");
}

}  // namespace
}  // namespace moslam
