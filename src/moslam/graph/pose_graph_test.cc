#include "moslam/graph/pose_graph.h"

#include <gtest/gtest.h>

#include "moslam/common/errors.h"

namespace moslam {
namespace {

SE3 Step() { return SE3(SO3::Exp(Vector3(0, 0, 0.1)), Vector3(1, 0, 0)); }

TEST(PoseGraph, CostSumsFactorsAndPriors) {
  PoseGraph g;
  g.add(RelativePoseFactor(Key::Pose(0, 0), Key::Pose(0, 1), Step(), 2.0 * Matrix6::Identity()));
  g.add(PriorFactor(Key::Pose(0, 0), SE3(), Matrix6::Identity()));
  Values v{{Key::Pose(0, 0), SE3()}, {Key::Pose(0, 1), SE3()}};
  const Vector6 r = SE3::Log(Step().inverse());
  EXPECT_NEAR(g.cost(v), r.squaredNorm(), 1e-12);  // 1/2 * 2 * |r|^2 + 0
  v.erase(Key::Pose(0, 1));
  EXPECT_THROW(g.cost(v), InvalidInputError);
}

TEST(PoseGraph, AnchorIsFirstPoseOfRobotZero) {
  PoseGraph g;
  g.add(RelativePoseFactor(Key::Pose(1, 0), Key::Pose(0, 5), Step(), Matrix6::Identity()));
  g.add(RelativePoseFactor(Key::Pose(0, 5), Key::Pose(0, 9), Step(), Matrix6::Identity()));
  EXPECT_EQ(GaugeAnchor(g), Key::Pose(0, 5));
  EXPECT_EQ(g.numRobots(), 2);
  PoseGraph h;
  h.add(RelativePoseFactor(Key::Pose(1, 0), Key::Pose(1, 1), Step(), Matrix6::Identity()));
  EXPECT_THROW(GaugeAnchor(h), UnderdeterminedError);
}

TEST(PoseGraph, FindsComponentsThatNothingAnchors) {
  PoseGraph g;
  g.add(RelativePoseFactor(Key::Pose(0, 0), Key::Pose(0, 1), Step(), Matrix6::Identity()));
  g.add(RelativePoseFactor(Key::Pose(1, 0), Key::Pose(1, 1), Step(), Matrix6::Identity()));
  EXPECT_EQ(UnreachableFrom(g, Key::Pose(0, 0)).size(), 2u);
  g.add(PriorFactor(Key::Pose(1, 1), SE3(), Matrix6::Identity()));  // a prior anchors it
  EXPECT_TRUE(UnreachableFrom(g, Key::Pose(0, 0)).empty());
}

}  // namespace
}  // namespace moslam
