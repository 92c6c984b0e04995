#include "moslam/graph/synthetic.h"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <string>

#include "moslam/common/errors.h"
#include "moslam/common/throws_naming_testing.h"

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
  // `change` applied to the default options makes MakeSyntheticGraph refuse them, naming `field`.
  const auto refused = [](const std::function<void(SyntheticGraphOptions&)>& change,
                          const std::string& field) {
    SyntheticGraphOptions o;
    change(o);
    return test::ThrowsNaming([&] { MakeSyntheticGraph(o); }, field);
  };
  EXPECT_TRUE(refused([](SyntheticGraphOptions& o) { o.num_robots = 0; }, "num_robots"));
  EXPECT_TRUE(refused([](SyntheticGraphOptions& o) { o.poses_per_robot = 1; }, "poses_per_robot"));
  EXPECT_TRUE(
      refused([](SyntheticGraphOptions& o) { o.sigma_rotation = std::nan(""); }, "sigma_rotation"));
  EXPECT_TRUE(
      refused([](SyntheticGraphOptions& o) { o.sigma_translation = -0.1; }, "sigma_translation"));
  EXPECT_TRUE(refused([](SyntheticGraphOptions& o) { o.loop_closure_radius = INFINITY; },
                      "loop_closure_radius"));
  EXPECT_TRUE(refused([](SyntheticGraphOptions& o) { o.max_loop_closures_per_pose = -1; },
                      "max_loop_closures_per_pose"));
}

}  // namespace
}  // namespace moslam
