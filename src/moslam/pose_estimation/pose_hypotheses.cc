#include "moslam/pose_estimation/pose_hypotheses.h"

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>

namespace moslam::pose_detail {
namespace {

constexpr double kPi = 3.14159265358979323846;

}  // namespace

Eigen::Vector3f Centroid(const FeatureCloud& cloud) {
  Eigen::Vector3f c = Eigen::Vector3f::Zero();
  for (const auto& p : cloud.points) c += p.getVector3fMap();
  return c / static_cast<float>(std::max<std::size_t>(1, cloud.size()));
}

FeatureCloud::Ptr FrontFaces(const ObjectTemplate& tmpl, const Eigen::Matrix4f& object_T_camera,
                             const RegistrationConfig& config) {
  const Eigen::Vector3f camera_in_object = object_T_camera.topRightCorner<3, 1>();
  auto target = std::make_shared<FeatureCloud>();
  for (const auto& q : tmpl.cloud->points) {
    if (q.getNormalVector3fMap().dot(camera_in_object - q.getVector3fMap()) > 0.0f) {
      target->push_back(q);
    }
  }
  if (static_cast<int>(target->size()) < config.min_segment_points) return tmpl.cloud;
  return target;
}

std::vector<Eigen::Matrix4f> SymmetryHypotheses(const FeatureCloud& source,
                                                const ObjectTemplate& tmpl,
                                                const Eigen::Matrix4f& initial,
                                                const RegistrationConfig& config) {
  std::vector<Eigen::Matrix4f> out{initial};
  const Eigen::Vector3f centroid = Centroid(source);
  const Eigen::Vector3f horizontal(1.0f, 1.0f, 0.0f);
  const Eigen::Vector3f c = (Eigen::Affine3f(initial) * centroid).cwiseProduct(horizontal);
  for (int j = 1; j < config.symmetry_turns; ++j) {
    const float angle = static_cast<float>(2.0 * kPi * j / config.symmetry_turns);
    const Eigen::Matrix3f R = Eigen::AngleAxisf(angle, Eigen::Vector3f::UnitZ()).toRotationMatrix();
    for (const Eigen::Vector3f& pivot : {Eigen::Vector3f::Zero().eval(), c}) {
      Eigen::Matrix4f turn = Eigen::Matrix4f::Identity();
      turn.topLeftCorner<3, 3>() = R;
      turn.topRightCorner<3, 1>() = pivot - R * pivot;
      out.push_back(turn * initial);
    }
    Eigen::Matrix4f recentred = out.back();
    const Eigen::Vector3f front_centroid = Centroid(*FrontFaces(tmpl, recentred, config));
    recentred.topRightCorner<3, 1>() += (front_centroid - c).cwiseProduct(horizontal);
    out.push_back(recentred);
  }
  return out;
}

std::vector<Eigen::Matrix4f> UprightHypotheses(const FeatureCloud& source,
                                               const ObjectTemplate& tmpl,
                                               const RegistrationConfig& config) {
  std::vector<Eigen::Matrix4f> out;
  if (config.upright_yaws <= 0 || source.empty()) return out;
  Eigen::Vector3f lo = Eigen::Vector3f::Constant(std::numeric_limits<float>::max()), hi = -lo;
  for (const auto& q : tmpl.cloud->points) {
    lo = lo.cwiseMin(q.getVector3fMap());
    hi = hi.cwiseMax(q.getVector3fMap());
  }
  if (std::max(hi.x() - lo.x(), hi.y() - lo.y()) < config.upright_min_extent) return out;
  const Eigen::Vector3f template_centroid = Centroid(*tmpl.cloud);
  // Level frame in the camera frame: z up, x the camera's forward axis made horizontal.
  const Eigen::Vector3f up = config.camera_up.cast<float>().normalized();
  Eigen::Vector3f forward = Eigen::Vector3f::UnitZ() - up * up.z();
  if (forward.norm() < 1e-3f) forward = Eigen::Vector3f::UnitX() - up * up.x();
  forward.normalize();
  Eigen::Matrix3f level;  // columns: the level frame's axes in the camera frame
  level << forward, up.cross(forward), up;
  const Eigen::Vector3f centroid = Centroid(source);
  Eigen::Matrix2f scatter = Eigen::Matrix2f::Zero();
  for (const auto& p : source.points) {
    const Eigen::Vector2f h = (level.transpose() * (p.getVector3fMap() - centroid)).head<2>();
    scatter += h * h.transpose();
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2f> eig(scatter);
  const Eigen::Vector2f axis = eig.eigenvectors().col(1);  // largest eigenvalue
  const float yaw0 = std::atan2(axis.y(), axis.x());
  for (int k = 0; k < config.upright_yaws; ++k) {
    const float yaw = yaw0 + static_cast<float>(2.0 * kPi * k / config.upright_yaws);
    const Eigen::Matrix3f R =  // camera_R_object
        level * Eigen::AngleAxisf(yaw, Eigen::Vector3f::UnitZ()).toRotationMatrix();
    Eigen::Matrix4f camera_T_object = Eigen::Matrix4f::Identity();
    camera_T_object.topLeftCorner<3, 3>() = R;
    camera_T_object.topRightCorner<3, 1>() = centroid - R * template_centroid;
    // Centre the points facing the camera from there on the segment (twice: the visible set
    // depends on where the object is).
    for (int pass = 0; pass < 2; ++pass) {
      const Eigen::Matrix4f object_T_camera = camera_T_object.inverse();
      camera_T_object.topRightCorner<3, 1>() =
          centroid - R * Centroid(*FrontFaces(tmpl, object_T_camera, config));
    }
    out.push_back(camera_T_object.inverse());
  }
  return out;
}

}  // namespace moslam::pose_detail
