#include "moslam/pose_estimation/pose_score.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <memory>

#include "moslam/pose_estimation/features.h"
#include "moslam/pose_estimation/test_shapes.h"
#include "moslam/render/rgbd.h"

namespace moslam::pose_detail {
namespace {

// The synthetic chair-like object as a template cloud (the score reads the cloud only).
ObjectTemplate TemplateOfTestObject() {
  ObjectTemplate t;
  t.label = "test_chair";
  t.cloud = std::make_shared<FeatureCloud>(ModelCloud(test::MakeTestObject(0.005)));
  return t;
}

// camera_T_object: the object 1.6 m in front of a level camera, turned by 0.6 rad about its
// vertical axis.
SE3 Truth() {
  const SE3 body_T_object(SO3::Exp(Vector3(0.0, 0.0, 0.6)), Vector3(1.6, 0.1, -0.05));
  return BodyFromCamera().inverse() * body_T_object;
}

// The segment registration would score: a noisy view of the object, voxelled, with normals.
FeatureCloud::Ptr Segment(const OrganizedCloud& view) {
  return PrepareSurface(view, FeatureConfig{}, 30);
}

Eigen::Matrix4f ObjectFromCamera(const SE3& camera_T_object) {
  return camera_T_object.inverse().matrix().cast<float>();
}

TEST(PoseScore, TheTruePoseAgreesInShapeAndColour) {
  const ObjectTemplate tmpl = TemplateOfTestObject();
  const RegistrationConfig config;
  const FeatureCloud::Ptr segment =
      Segment(*test::ViewOf(test::MakeTestObject(0.005), Truth(), 0.002, 3u));
  ASSERT_GT(segment->size(), 100u);
  const PoseScore s = ScorePose(*segment, tmpl, ObjectFromCamera(Truth()), config, true);
  EXPECT_GT(s.geometric, 0.97);
  EXPECT_GT(s.colour, 0.85);  // 0.90 measured (the stripes' edges blur in the voxels)
  EXPECT_NEAR(s.score, s.geometric * s.colour, 1e-12);
  EXPECT_GT(s.covered, 0.97);
  EXPECT_TRUE(ShapeAgrees(s, config));
  EXPECT_EQ(ScorePose(*segment, tmpl, ObjectFromCamera(Truth()), config).covered, 0.0);
}

TEST(PoseScore, APoseTurnedAwayFromTheTruthDoesNotAgreeInShape) {
  const ObjectTemplate tmpl = TemplateOfTestObject();
  const RegistrationConfig config;
  const FeatureCloud::Ptr segment =
      Segment(*test::ViewOf(test::MakeTestObject(0.005), Truth(), 0.002, 3u));
  // A quarter turn of the object about its vertical axis, and 10 cm along each axis.
  const SE3 turned = Truth() * SE3(SO3::Exp(Vector3(0.0, 0.0, 1.57)), Vector3::Zero());
  const SE3 shifted = Truth() * SE3(SO3(), Vector3(0.1, 0.1, 0.1));
  for (const SE3& wrong : {turned, shifted}) {
    const PoseScore s = ScorePose(*segment, tmpl, ObjectFromCamera(wrong), config, true);
    EXPECT_LT(s.geometric, config.min_geometric_agreement_covered);
    EXPECT_FALSE(ShapeAgrees(s, config));
  }
}

TEST(PoseScore, ColourOfAnotherObjectFailsTheColourAgreementOnly) {
  const ObjectTemplate tmpl = TemplateOfTestObject();
  const RegistrationConfig config;
  const FeatureCloud::Ptr segment =
      Segment(*test::ViewOf(test::MakeTestObject(0.005), Truth(), 0.002, 3u));
  const PoseScore right = ScorePose(*segment, tmpl, ObjectFromCamera(Truth()), config);
  FeatureCloud green = *segment;
  for (auto& p : green.points) {
    p.r = 20;
    p.g = 200;
    p.b = 20;
  }
  const PoseScore s = ScorePose(green, tmpl, ObjectFromCamera(Truth()), config);
  EXPECT_EQ(s.geometric, right.geometric);
  EXPECT_LT(s.colour, config.min_colour_agreement);
  // Shading (the same colours, 60 % as bright) is not another colour.
  FeatureCloud shaded = *segment;
  for (auto& p : shaded.points) {
    p.r = static_cast<std::uint8_t>(0.6 * p.r);
    p.g = static_cast<std::uint8_t>(0.6 * p.g);
    p.b = static_cast<std::uint8_t>(0.6 * p.b);
  }
  EXPECT_NEAR(ScorePose(shaded, tmpl, ObjectFromCamera(Truth()), config).colour, right.colour,
              0.02);
}

// Points beside the object (off the template's pixels) lower the geometric agreement but not the
// covered one: the second clause of the SHAPE RULE accepts the pose. Points in front of the
// object, on its pixels, lower both.
TEST(PoseScore, ClutterBesideTheObjectIsNotEvidenceAgainstThePoseButClutterOnItIs) {
  const ObjectTemplate tmpl = TemplateOfTestObject();
  const RegistrationConfig config;
  const FeatureCloud::Ptr segment =
      Segment(*test::ViewOf(test::MakeTestObject(0.005), Truth(), 0.002, 3u));
  const Vector3 centre = Truth().translation();  // camera frame
  // A patch of 20 % of the segment's points, 1 m to the right of (beside) or 0.4 m in front of
  // (on the pixels of) the object's centre.
  auto with_patch = [&](const Vector3& at) {
    FeatureCloud out = *segment;
    const int n = static_cast<int>(segment->size() / 4);
    const int side = static_cast<int>(std::ceil(std::sqrt(n)));
    for (int i = 0; i < n; ++i) {
      FeaturePoint p = (*segment)[0];
      p.x = static_cast<float>(at.x() + 0.02 * (i % side - side / 2));
      p.y = static_cast<float>(at.y() + 0.02 * (i / side - side / 2));
      p.z = static_cast<float>(at.z());
      out.push_back(p);
    }
    return out;
  };
  const FeatureCloud beside = with_patch(centre + Vector3(1.0, 0.0, 0.0));
  const PoseScore b = ScorePose(beside, tmpl, ObjectFromCamera(Truth()), config, true);
  EXPECT_LT(b.geometric, config.min_geometric_agreement);
  EXPECT_GE(b.geometric, config.min_geometric_agreement_covered);
  EXPECT_GT(b.covered, config.min_covered_agreement);
  EXPECT_TRUE(ShapeAgrees(b, config));
  EXPECT_FALSE(ShapeAgrees(ScorePose(beside, tmpl, ObjectFromCamera(Truth()), config), config));

  const FeatureCloud in_front = with_patch(centre - Vector3(0.0, 0.0, 0.4));
  const PoseScore f = ScorePose(in_front, tmpl, ObjectFromCamera(Truth()), config, true);
  EXPECT_LT(f.geometric, config.min_geometric_agreement);
  EXPECT_LT(f.covered, config.min_covered_agreement);
  EXPECT_FALSE(ShapeAgrees(f, config));
}

TEST(PoseScore, TheRadiusWidensWithTheDepthNoise) {
  const AxialDepthNoise noise;
  EXPECT_DOUBLE_EQ(WidenedByDepthNoise(0.025, 3.0, 0.0, noise), 0.025);
  const double s = noise.sigma(3.0);
  EXPECT_DOUBLE_EQ(WidenedByDepthNoise(0.025, 3.0, 2.0, noise),
                   std::sqrt(0.025 * 0.025 + 4.0 * s * s));
  EXPECT_LT(WidenedByDepthNoise(0.025, 2.0, 1.0, noise),
            WidenedByDepthNoise(0.025, 4.0, 1.0, noise));
}

TEST(PoseScore, ChromaIsShadingInvariantAndPullsDarkColoursToGrey) {
  FeaturePoint bright, dim, dark;
  bright.r = 200, bright.g = 100, bright.b = 40;
  dim.r = 100, dim.g = 50, dim.b = 20;
  dark.r = 10, dark.g = 5, dark.b = 2;
  EXPECT_NEAR(Chroma(bright, 10.0f).sum(), 1.0f, 1e-6f);
  EXPECT_LT((Chroma(bright, 0.0f) - Chroma(dim, 0.0f)).norm(), 1e-6f);
  // dark and bright have one chromaticity at k = 0; the offset moves the dark one most of the way
  // to grey and the bright one little.
  const Eigen::Vector3f grey = Eigen::Vector3f::Constant(1.0f / 3.0f);
  auto from_grey = [&](const FeaturePoint& p, float k) { return (Chroma(p, k) - grey).norm(); };
  EXPECT_LT((Chroma(dark, 0.0f) - Chroma(bright, 0.0f)).norm(), 1e-6f);
  EXPECT_LT(from_grey(dark, 10.0f), from_grey(dark, 0.0f) / 2.0f);
  EXPECT_GT(from_grey(bright, 10.0f), 0.9f * from_grey(bright, 0.0f));
}

}  // namespace
}  // namespace moslam::pose_detail
