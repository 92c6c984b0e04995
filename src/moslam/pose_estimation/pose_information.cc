#include "moslam/pose_estimation/pose_information.h"

#include <pcl/kdtree/kdtree_flann.h>

#include <Eigen/Cholesky>
#include <Eigen/Geometry>
#include <algorithm>
#include <vector>

#include "moslam/pose_estimation/pose_hypotheses.h"

namespace moslam {

double InformationFloorScale(double mean_depth, const RegistrationConfig& config) {
  if (config.information_floor_noise <= 0.0 || !(mean_depth > 0.0)) return 1.0;
  return std::max(1.0, config.depth_noise.sigma(mean_depth) / config.information_floor_noise);
}

namespace pose_detail {
namespace {

constexpr double kDegToRad = 3.14159265358979323846 / 180.0;

}  // namespace

Matrix6 AlignmentInformation(const FeatureCloud& source, const FeatureCloud::Ptr& target,
                             const Eigen::Matrix4f& object_T_camera,
                             const RegistrationConfig& config) {
  std::vector<int> nn_index(1);
  std::vector<float> nn_sq(1);
  pcl::KdTreeFLANN<FeaturePoint> point_tree;
  point_tree.setInputCloud(target);
  const Eigen::Affine3f T_final(object_T_camera);
  const float max_sq = static_cast<float>(config.gicp_max_correspondence_distance *
                                          config.gicp_max_correspondence_distance);
  Matrix6 H = Matrix6::Zero();
  double sum_sq = 0.0;
  int n = 0;
  for (const auto& sp : source.points) {
    FeaturePoint y;
    y.getVector3fMap() = T_final * sp.getVector3fMap();
    if (point_tree.nearestKSearch(y, 1, nn_index, nn_sq) != 1 || nn_sq[0] > max_sq) continue;
    const FeaturePoint& q = (*target)[static_cast<std::size_t>(nn_index[0])];
    const Vector3 yd = y.getVector3fMap().cast<double>();
    const Vector3 nd = q.getNormalVector3fMap().cast<double>();
    const Vector3 qd = q.getVector3fMap().cast<double>();
    Vector6 J;
    J.head<3>() = nd.cross(yd);
    J.tail<3>() = -nd;
    H += J * J.transpose();
    const double r = nd.dot(yd - qd);
    sum_sq += r * r;
    ++n;
  }
  const double s2 = std::max(n > 0 ? sum_sq / n : 0.0,
                             config.information_sigma_point * config.information_sigma_point);
  const double deflate = n > 0 ? std::min(1.0, config.information_max_effective_points / n) : 1.0;
  const Matrix6 H_scaled = H * (deflate / s2) + 1e-6 * Matrix6::Identity();
  Matrix6 Sigma = H_scaled.ldlt().solve(Matrix6::Identity());
  const double scale = InformationFloorScale(Centroid(source).z(), config);
  const double sr = scale * config.sigma_rotation_floor_deg * kDegToRad;
  const double st = scale * config.sigma_translation_floor;
  Sigma.diagonal().head<3>().array() += sr * sr;
  Sigma.diagonal().tail<3>().array() += st * st;
  Sigma = 0.5 * (Sigma + Sigma.transpose());
  Matrix6 info = Sigma.ldlt().solve(Matrix6::Identity());
  return 0.5 * (info + info.transpose());
}

}  // namespace pose_detail
}  // namespace moslam
