#include "moslam/pose_estimation/pose_hypotheses.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <memory>

#include "moslam/pose_estimation/features.h"
#include "moslam/pose_estimation/test_shapes.h"
#include "moslam/render/rgbd.h"

namespace moslam::pose_detail {
namespace {

constexpr double kPi = 3.14159265358979323846;

// The synthetic chair-like object (0.5 m wide) as a template cloud (the hypotheses read the
// cloud only).
ObjectTemplate TemplateOfTestObject() {
  ObjectTemplate t;
  t.label = "test_chair";
  t.cloud = std::make_shared<FeatureCloud>(ModelCloud(test::MakeTestObject(0.005)));
  return t;
}

// camera_T_object: the object 1.6 m in front of a level camera, turned by `yaw`.
SE3 InFront(double yaw) {
  const SE3 body_T_object(SO3::Exp(Vector3(0.0, 0.0, yaw)), Vector3(1.6, 0.1, -0.05));
  return BodyFromCamera().inverse() * body_T_object;
}

FeatureCloud::Ptr SegmentOf(const SE3& camera_T_object) {
  return PrepareSurface(*test::ViewOf(test::MakeTestObject(0.005), camera_T_object, 0.002, 5u),
                        FeatureConfig{}, 30);
}

// The angle of a rotation about the z axis (and how far it is from being one).
double YawOf(const Eigen::Matrix3f& R, double* off_axis) {
  const Eigen::AngleAxisf aa(R);
  const double angle = aa.angle();
  *off_axis = angle > 1e-4 ? std::abs(std::abs(aa.axis().z()) - 1.0) : 0.0;
  return aa.axis().z() >= 0.0f ? angle : -angle;
}

TEST(PoseHypotheses, CentroidIsTheMeanAndZeroForNoPoints) {
  FeatureCloud cloud;
  EXPECT_EQ(Centroid(cloud), Eigen::Vector3f::Zero());
  FeaturePoint a, b;
  a.x = 1.0f, a.y = 2.0f, a.z = 3.0f;
  b.x = 3.0f, b.y = -2.0f, b.z = 1.0f;
  cloud.push_back(a);
  cloud.push_back(b);
  EXPECT_TRUE(Centroid(cloud).isApprox(Eigen::Vector3f(2.0f, 0.0f, 2.0f)));
}

TEST(PoseHypotheses, FrontFacesKeepsThePointsFacingTheCameraOrTheWholeTemplate) {
  const ObjectTemplate tmpl = TemplateOfTestObject();
  RegistrationConfig config;
  const Eigen::Matrix4f object_T_camera = InFront(0.6).inverse().matrix().cast<float>();
  const FeatureCloud::Ptr front = FrontFaces(tmpl, object_T_camera, config);
  const Eigen::Vector3f camera = object_T_camera.topRightCorner<3, 1>();
  ASSERT_GT(front->size(), 100u);
  EXPECT_LT(front->size(), tmpl.cloud->size() * 3 / 4);
  for (const auto& q : front->points) {
    EXPECT_GT(q.getNormalVector3fMap().dot(camera - q.getVector3fMap()), 0.0f);
  }
  config.min_segment_points = static_cast<int>(front->size()) + 1;
  EXPECT_EQ(FrontFaces(tmpl, object_T_camera, config), tmpl.cloud);
}

TEST(PoseHypotheses, SymmetryHypothesesAreTheInitialPoseAndItsTurnsAboutTheVertical) {
  const ObjectTemplate tmpl = TemplateOfTestObject();
  const FeatureCloud::Ptr segment = SegmentOf(InFront(0.6));
  const Eigen::Matrix4f initial = InFront(0.5).inverse().matrix().cast<float>();
  RegistrationConfig config;
  for (int turns : {1, 2, 4}) {
    config.symmetry_turns = turns;
    const auto h = SymmetryHypotheses(*segment, tmpl, initial, config);
    ASSERT_EQ(h.size(), static_cast<std::size_t>(1 + 3 * (turns - 1))) << turns;
    EXPECT_EQ(h[0], initial);
    const Eigen::Vector3f mapped_centroid = Eigen::Affine3f(initial) * Centroid(*segment);
    for (int j = 1; j < turns; ++j) {
      const double expected = 2.0 * kPi * j / turns;
      for (int k = 0; k < 3; ++k) {
        const Eigen::Matrix4f& pose = h[static_cast<std::size_t>(1 + 3 * (j - 1) + k)];
        // pose = turn * initial, the turn about the object's vertical axis.
        const Eigen::Matrix4f turn = pose * initial.inverse();
        double off_axis = 0.0;
        const double yaw = YawOf(turn.topLeftCorner<3, 3>(), &off_axis);
        EXPECT_LT(off_axis, 1e-5) << turns << " " << j << " " << k;
        EXPECT_NEAR(std::remainder(yaw - expected, 2.0 * kPi), 0.0, 1e-5);
        EXPECT_NEAR(turn(2, 3), 0.0, 1e-5);  // no vertical shift
        const Eigen::Vector3f c = Eigen::Affine3f(pose) * Centroid(*segment);
        if (k == 0) {  // about the object's origin
          EXPECT_LT((turn.topRightCorner<3, 1>().norm()), 1e-5);
        } else if (k == 1) {  // about the vertical line through the segment's centroid
          EXPECT_LT((c - mapped_centroid).norm(), 1e-4);
        } else {  // that pose, the segment's centroid moved onto the template's facing points
          const Eigen::Matrix4f& pivot_pose = h[static_cast<std::size_t>(3 * (j - 1) + 2)];
          const Eigen::Vector3f facing = Centroid(*FrontFaces(tmpl, pivot_pose, config));
          EXPECT_LT((c.head<2>() - facing.head<2>()).norm(), 1e-4);
          EXPECT_NEAR(c.z(), mapped_centroid.z(), 1e-4);
        }
      }
    }
  }
}

TEST(PoseHypotheses, UprightHypothesesStandTheObjectOnTheFloorAtQuarterTurns) {
  const ObjectTemplate tmpl = TemplateOfTestObject();
  const FeatureCloud::Ptr segment = SegmentOf(InFront(0.6));
  RegistrationConfig config;
  config.upright_min_extent = 0.4;  // the test object is 0.5 m wide
  for (const Vector3& up : {Vector3(0.0, -1.0, 0.0), Vector3(0.0, -1.0, 0.2).normalized()}) {
    config.camera_up = up;
    const auto h = UprightHypotheses(*segment, tmpl, config);
    ASSERT_EQ(h.size(), static_cast<std::size_t>(config.upright_yaws));
    for (std::size_t k = 0; k < h.size(); ++k) {
      const Eigen::Matrix4f camera_T_object = h[k].inverse();
      // The object's z axis is the floor's up direction.
      EXPECT_LT((camera_T_object.block<3, 1>(0, 2) - up.cast<float>()).norm(), 1e-5);
      // Its camera-facing points are centred on the segment.
      const Eigen::Vector3f facing =
          Eigen::Affine3f(camera_T_object) * Centroid(*FrontFaces(tmpl, h[k], config));
      EXPECT_LT((facing - Centroid(*segment)).norm(), 0.03) << k;
      // Consecutive hypotheses a quarter turn apart about that axis.
      const Eigen::Matrix4f next = h[(k + 1) % h.size()].inverse();
      double off_axis = 0.0;
      const double yaw =
          YawOf(camera_T_object.topLeftCorner<3, 3>().transpose() * next.topLeftCorner<3, 3>(),
                &off_axis);
      EXPECT_LT(off_axis, 1e-4);
      EXPECT_NEAR(std::remainder(yaw - kPi / 2.0, 2.0 * kPi), 0.0, 1e-4);
    }
  }
  config.camera_up = Vector3(0.0, -1.0, 0.0);
  config.upright_yaws = 0;
  EXPECT_TRUE(UprightHypotheses(*segment, tmpl, config).empty());
  config.upright_yaws = 4;
  config.upright_min_extent = 0.8;  // not a large object
  EXPECT_TRUE(UprightHypotheses(*segment, tmpl, config).empty());
  config.upright_min_extent = 0.4;
  EXPECT_TRUE(UprightHypotheses(FeatureCloud(), tmpl, config).empty());
}

}  // namespace
}  // namespace moslam::pose_detail
