#include "moslam/pose_estimation/symmetry.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <utility>
#include <vector>

#include "moslam/pose_estimation/test_shapes.h"

namespace moslam {
namespace {

constexpr double kPi = 3.14159265358979323846;

// A box of one colour centred on the object origin (a fridge, a cabinet): width x depth x height.
ObjectTemplate PlainBox(double width, double depth, double height) {
  ColoredPointSet s;
  test::SampleBox({Vector3(-width / 2, -depth / 2, -height / 2),
                   Vector3(width / 2, depth / 2, height / 2)},
                  0.01, s);
  for (auto& c : s.colours_bgr) c = {180, 190, 200};
  return MakeObjectTemplate("box", s);
}

SE3 Turn(double angle) { return SE3(SO3::Exp(Vector3(0.0, 0.0, angle)), Vector3::Zero()); }

Eigen::Matrix4f AsMatrix(const SE3& T) { return T.matrix().cast<float>(); }

TEST(TemplateSelfAgreement, MeasuresWhatTheScoreCanTellApart) {
  const RegistrationConfig config;
  const ObjectTemplate square = PlainBox(0.6, 0.6, 1.2);   // a fridge's footprint
  const ObjectTemplate oblong = PlainBox(0.8, 0.4, 1.0);   // a cabinet's
  const ObjectTemplate chair = MakeObjectTemplate("chair", test::MakeTestObject(0.005));
  const double sq_quarter = TemplateSelfAgreement(square, Turn(kPi / 2), config);
  const double ob_half = TemplateSelfAgreement(oblong, Turn(kPi), config);
  const double ob_quarter = TemplateSelfAgreement(oblong, Turn(kPi / 2), config);
  const double ch_half = TemplateSelfAgreement(chair, Turn(kPi), config);
  const double ch_quarter = TemplateSelfAgreement(chair, Turn(kPi / 2), config);
  std::printf("  square box quarter turn %.3f; oblong half %.3f quarter %.3f; chair half %.3f "
              "quarter %.3f\n",
              sq_quarter, ob_half, ob_quarter, ch_half, ch_quarter);
  EXPECT_DOUBLE_EQ(TemplateSelfAgreement(chair, SE3(), config), 1.0);
  EXPECT_GT(sq_quarter, 0.95);
  EXPECT_GT(ob_half, 0.95);
  EXPECT_LT(ob_quarter, 0.6);  // its long sides land where its short ones were
  EXPECT_LT(ch_half, 0.7);     // asymmetric in shape and colour
  EXPECT_LT(ch_quarter, 0.7);
  // A shift the size of the box's depth: no longer the same surface.
  EXPECT_LT(TemplateSelfAgreement(oblong, SE3(SO3(), Vector3(0.2, 0.0, 0.0)), config), 0.7);
  // Another colour on one side: the half turn puts it where the plain side was.
  ColoredPointSet s;
  test::SampleBox({Vector3(-0.4, -0.2, -0.5), Vector3(0.4, 0.2, 0.5)}, 0.01, s);
  for (std::size_t i = 0; i < s.size(); ++i) {
    s.colours_bgr[i] = s.points[i].x() > 0.0 ? cv::Vec3b(40, 60, 200) : cv::Vec3b(180, 190, 200);
  }
  EXPECT_LT(TemplateSelfAgreement(MakeObjectTemplate("two_tone", s), Turn(kPi), config), 0.7);
}

// The coarse poses of an oblong box seen by a camera 2 m away; the winner failed the gate. Only a
// pose that the score ranks alike (margin), on another side of the object that the template cannot
// tell apart (a half turn; not a quarter turn, nor the winner's pose again) and that holds the
// gate on its own is tried.
TEST(SymmetricTieBreak, TriesOnlyPosesTheScoreCannotTellApartAndTheGateHolds) {
  RegistrationConfig config;
  const ObjectTemplate oblong = PlainBox(0.8, 0.4, 1.0);
  const SE3 winner(SO3::Exp(Vector3(0.1, -0.2, 0.3)), Vector3(0.1, 0.4, 2.0));
  // Each pose also lifted by its own millimetre, so that the gate count can tell them apart.
  auto pose = [&](double turn, int k) {
    return AsMatrix(SE3(SO3(), Vector3(0.0, 0.0, 0.001 * k)) * Turn(turn) * winner);
  };
  const std::vector<CoarsePose> ranked{
      {0, pose(0.0, 0), 0.80},
      {3, pose(kPi / 2, 1), 0.795},  // quarter turn: the template tells it apart
      {4, pose(kPi, 2), 0.79},       // half turn, within the margin, holds the gate
      {5, pose(-kPi, 3), 0.785},     // the same, but too few inliers
      {6, pose(kPi, 4), 0.75},       // half turn, outside the margin
      {7, pose(0.02, 5), 0.799},     // the winner's pose again (1 deg, 5 mm off)
  };
  const int inliers[] = {8, 30, 14, 11, 40, 25};
  auto gate_count = [&](const Eigen::Matrix4f& object_T_camera) {
    for (std::size_t i = 0; i < ranked.size(); ++i) {
      if (ranked[i].object_T_camera == object_T_camera) return inliers[i];
    }
    ADD_FAILURE() << "gate counted at a pose that is not a coarse pose";
    return 0;
  };
  std::vector<std::size_t> order = SymmetricTieBreakOrder(ranked, oblong, gate_count, config);
  ASSERT_EQ(order.size(), 1u);
  EXPECT_EQ(order[0], 2u);
  // A wider margin admits the far half turn too, best first.
  config.tie_break_score_margin = 0.06;
  order = SymmetricTieBreakOrder(ranked, oblong, gate_count, config);
  ASSERT_EQ(order.size(), 2u);
  EXPECT_EQ(order[0], 2u);
  EXPECT_EQ(order[1], 4u);
  // A chair is never tie-broken; nor anything with the rule off.
  const ObjectTemplate chair = MakeObjectTemplate("chair", test::MakeTestObject(0.005));
  EXPECT_TRUE(SymmetricTieBreakOrder(ranked, chair, gate_count, config).empty());
  config.symmetric_tie_break = false;
  EXPECT_TRUE(SymmetricTieBreakOrder(ranked, oblong, gate_count, config).empty());
}

}  // namespace
}  // namespace moslam
