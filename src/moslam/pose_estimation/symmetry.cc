#include "moslam/pose_estimation/symmetry.h"

#include <pcl/kdtree/kdtree_flann.h>

#include <algorithm>
#include <cmath>

namespace moslam {
namespace {
constexpr double kPi = 3.14159265358979323846;
}  // namespace

double TemplateSelfAgreement(const ObjectTemplate& tmpl, const SE3& motion,
                             const RegistrationConfig& config) {
  if (!tmpl.cloud || tmpl.cloud->empty()) return 0.0;
  const FeatureCloud& cloud = *tmpl.cloud;
  pcl::KdTreeFLANN<FeaturePoint> tree;
  tree.setInputCloud(tmpl.cloud);
  const Eigen::Affine3f moved(motion.matrix().cast<float>());
  const auto k = static_cast<float>(config.chroma_dark_offset);
  const auto tol_sq = static_cast<float>(config.colour_tolerance * config.colour_tolerance);
  const auto radius = static_cast<float>(config.score_distance);
  constexpr std::size_t kMaxQueries = 2000;
  const std::size_t stride = std::max<std::size_t>(1, (cloud.size() + kMaxQueries - 1) / kMaxQueries);
  std::vector<int> idx;
  std::vector<float> sq;
  int agree = 0, queries = 0;
  for (std::size_t i = 0; i < cloud.size(); i += stride) {
    ++queries;
    const FeaturePoint& q = cloud[i];
    FeaturePoint y = q;
    y.getVector3fMap() = moved * q.getVector3fMap();
    if (tree.radiusSearch(y, radius, idx, sq) <= 0) continue;
    const Eigen::Vector3f cq = pose_detail::Chromaticity(q, k);
    for (int j : idx) {
      const FeaturePoint& t = cloud[static_cast<std::size_t>(j)];
      if ((pose_detail::Chromaticity(t, k) - cq).squaredNorm() <= tol_sq) {
        ++agree;
        break;
      }
    }
  }
  return static_cast<double>(agree) / queries;
}

std::vector<std::size_t> SymmetricTieBreakOrder(
    const std::vector<CoarsePose>& ranked, const ObjectTemplate& tmpl,
    const std::function<int(const Eigen::Matrix4f&)>& gate_count,
    const RegistrationConfig& config) {
  std::vector<std::size_t> out;
  if (!config.symmetric_tie_break || ranked.size() < 2) return out;
  const int turns = config.symmetry_turns;
  const double step = 2.0 * kPi / turns;
  std::vector<double> turn_agreement(static_cast<std::size_t>(turns), -1.0);  // lazily, per turn
  const Eigen::Matrix4f winner_inverse = ranked.front().object_T_camera.inverse();
  for (std::size_t i = 1; i < ranked.size(); ++i) {
    const CoarsePose& c = ranked[i];
    if (c.score < ranked.front().score - config.tie_break_score_margin) continue;
    const Eigen::Matrix4d motion = (c.object_T_camera * winner_inverse).cast<double>();
    // The object's turn about its vertical axis nearest the motion: not the winner's pose again.
    const double yaw = std::atan2(motion(1, 0), motion(0, 0));
    const int j = ((static_cast<int>(std::lround(yaw / step)) % turns) + turns) % turns;
    if (j == 0) continue;
    if (gate_count(c.object_T_camera) < config.min_inliers) continue;
    double& agreement = turn_agreement[static_cast<std::size_t>(j)];
    if (agreement < 0.0) {
      agreement = TemplateSelfAgreement(
          tmpl, SE3(SO3::Exp(Vector3(0.0, 0.0, j * step)), Vector3::Zero()), config);
    }
    if (agreement < config.min_symmetry_self_agreement) continue;
    const SE3 moved(SO3::FromMatrixNormalized(motion.topLeftCorner<3, 3>()),
                    motion.topRightCorner<3, 1>());
    if (TemplateSelfAgreement(tmpl, moved, config) < config.min_symmetry_self_agreement) continue;
    out.push_back(i);
  }
  return out;
}

}  // namespace moslam
