#include "moslam/pose_estimation/pose_information.h"

#include <gtest/gtest.h>

#include <memory>
#include <vector>

#include "moslam/geometry/se3.h"

namespace moslam::pose_detail {
namespace {

// Points on the faces of a box corner (object frame): the faces x = 0, y = 0, z = 0 of
// [0, 0.4]^3 for the listed axes, sampled at the centres of a `spacing` grid (no point on an edge),
// with outward normals (-x, -y, -z).
FeatureCloud::Ptr CornerFaces(const std::vector<int>& axes, double spacing) {
  auto out = std::make_shared<FeatureCloud>();
  const int n = static_cast<int>(0.4 / spacing);
  for (int axis : axes) {
    for (int i = 0; i < n; ++i) {
      for (int j = 0; j < n; ++j) {
        Vector3 p = Vector3::Zero();
        p[(axis + 1) % 3] = (i + 0.5) * spacing;
        p[(axis + 2) % 3] = (j + 0.5) * spacing;
        FeaturePoint q;
        q.getVector3fMap() = p.cast<float>();
        Eigen::Vector3f normal = Eigen::Vector3f::Zero();
        normal[axis] = -1.0f;
        q.getNormalVector3fMap() = normal;
        out->push_back(q);
      }
    }
  }
  return out;
}

// camera_T_object: the corner 1.5 m in front of the camera, turned so that all three faces face
// it.
SE3 CameraTObject() {
  return SE3(SO3::Exp(Vector3(0.5, -0.6, 0.3)), Vector3(0.1, -0.05, 1.5));
}

// The segment: the template's points seen in the camera frame.
FeatureCloud InCamera(const FeatureCloud& target, const SE3& camera_T_object) {
  FeatureCloud out;
  for (const auto& q : target.points) {
    FeaturePoint p;
    p.getVector3fMap() =
        camera_T_object.transformFrom(q.getVector3fMap().cast<double>()).cast<float>();
    out.push_back(p);
  }
  return out;
}

Eigen::Matrix4f ObjectTCamera(const SE3& camera_T_object) {
  return camera_T_object.inverse().matrix().cast<float>();
}

// With no deflation and negligible floors, the information is the point-to-plane Fisher
// information sum J^T J / sigma^2 (+ 1e-6 I), J the derivative of n_i . (y_i - q_i) for the
// right perturbation camera_T_object * Exp(xi): checked against central differences of that
// residual, y_i = (camera_T_object Exp(xi))^-1 p_i.
TEST(PoseInformation, IsThePointToPlaneFisherInformationOfTheRightPerturbation) {
  const FeatureCloud::Ptr target = CornerFaces({0, 1, 2}, 0.04);
  const SE3 T = CameraTObject();
  const FeatureCloud source = InCamera(*target, T);
  RegistrationConfig config;
  config.information_max_effective_points = 1e9;
  config.sigma_rotation_floor_deg = 1e-7;
  config.sigma_translation_floor = 1e-9;
  config.information_floor_noise = 0.0;
  const Matrix6 info = AlignmentInformation(source, target, ObjectTCamera(T), config);

  const double s2 = config.information_sigma_point * config.information_sigma_point;
  Matrix6 expected = 1e-6 * Matrix6::Identity();
  const double h = 1e-6;
  for (std::size_t i = 0; i < source.size(); ++i) {
    const Vector3 p = source[i].getVector3fMap().cast<double>();
    const Vector3 q = (*target)[i].getVector3fMap().cast<double>();
    const Vector3 n = (*target)[i].getNormalVector3fMap().cast<double>();
    const auto residual = [&](const Vector6& xi) {
      return n.dot((T * SE3::Exp(xi)).inverse().transformFrom(p) - q);
    };
    Vector6 J;
    for (int k = 0; k < 6; ++k) {
      const Vector6 d = h * Vector6::Unit(k);
      J[k] = (residual(d) - residual(-d)) / (2.0 * h);
    }
    expected += J * J.transpose() / s2;
  }
  EXPECT_LT((info - expected).norm(), 1e-3 * expected.norm());
  EXPECT_LT((info - info.transpose()).norm(), 1e-9 * info.norm());
}

// One face constrains its normal translation and the rotations about its in-plane axes, not
// sliding along it nor turning about its normal: those get ~1e-6 information (registration.h).
TEST(PoseInformation, AFlatFaceLeavesItsInPlaneMotionsUnconstrained) {
  const FeatureCloud::Ptr target = CornerFaces({2}, 0.02);  // the face z = 0
  const SE3 T = CameraTObject();
  const FeatureCloud source = InCamera(*target, T);
  const Matrix6 info = AlignmentInformation(source, target, ObjectTCamera(T), RegistrationConfig{});
  // Tangent order (w, v): w_z, v_x and v_y are free; v_z, w_x and w_y are constrained.
  for (int free : {2, 3, 4}) EXPECT_LT(info(free, free), 2e-6) << free;
  for (int held : {0, 1, 5}) EXPECT_GT(info(held, held), 1e2) << held;
  EXPECT_GT(info.ldlt().vectorD().minCoeff(), 0.0);  // positive definite
}

// Points of one surface are correlated: beyond information_max_effective_points the information
// no longer grows with the sampling density.
TEST(PoseInformation, DenserSamplingOfOneSurfaceAddsNoInformation) {
  const SE3 T = CameraTObject();
  RegistrationConfig config;  // floors negligible: they would cap the information
  config.sigma_rotation_floor_deg = 1e-7;
  config.sigma_translation_floor = 1e-9;
  config.information_floor_noise = 0.0;
  const FeatureCloud::Ptr coarse = CornerFaces({0, 1, 2}, 0.04);  // 300 points
  const FeatureCloud::Ptr dense = CornerFaces({0, 1, 2}, 0.02);   // 1200 points
  const Matrix6 a = AlignmentInformation(InCamera(*coarse, T), coarse, ObjectTCamera(T), config);
  const Matrix6 b = AlignmentInformation(InCamera(*dense, T), dense, ObjectTCamera(T), config);
  EXPECT_LT((a - b).norm(), 0.05 * a.norm());
  EXPECT_GT(a.trace(), 1e5);  // not the floors
  config.information_max_effective_points = 1e9;  // without deflation: about 4x
  const Matrix6 c = AlignmentInformation(InCamera(*coarse, T), coarse, ObjectTCamera(T), config);
  const Matrix6 d = AlignmentInformation(InCamera(*dense, T), dense, ObjectTCamera(T), config);
  EXPECT_GT(d.trace(), 3.0 * c.trace());
}

}  // namespace
}  // namespace moslam::pose_detail
