#include "moslam/pose_estimation/pose_score.h"

#include <pcl/kdtree/kdtree_flann.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <memory>
#include <optional>
#include <vector>

#include "moslam/pose_estimation/pose_hypotheses.h"

namespace moslam::pose_detail {

double WidenedByDepthNoise(double d0, double z, double sigmas, const AxialDepthNoise& noise) {
  const double widen = sigmas * noise.sigma(z);
  return std::sqrt(d0 * d0 + widen * widen);
}

Eigen::Vector3f Chroma(const FeaturePoint& p, float k) {
  const Eigen::Vector3f c(static_cast<float>(p.r) + k, static_cast<float>(p.g) + k,
                          static_cast<float>(p.b) + k);
  return c / c.sum();
}

namespace {

// The template points' rays: normalised image coordinates (x/z, y/z) of the points in front of
// the camera, for "does the template cover this pixel" (AGREEMENT RULE's covered(i)).
class TemplateRays {
 public:
  TemplateRays(const FeatureCloud& target, const Eigen::Affine3f& camera_T_object)
      : rays_(std::make_shared<pcl::PointCloud<pcl::PointXYZ>>()) {
    for (const auto& q : target.points) {
      const Eigen::Vector3f c = camera_T_object * q.getVector3fMap();
      if (c.z() > 0.0f) rays_->push_back(pcl::PointXYZ(c.x() / c.z(), c.y() / c.z(), 0.0f));
    }
    if (!rays_->empty()) tree_.setInputCloud(rays_);
  }
  // Whether a template point lies within `reach` (normalised units) of the ray through p.
  bool covers(const FeaturePoint& p, float reach) {
    if (rays_->empty() || !(p.z > 0.0f)) return false;
    return tree_.radiusSearch(pcl::PointXYZ(p.x / p.z, p.y / p.z, 0.0f), reach, idx_, sq_, 1) > 0;
  }

 private:
  pcl::PointCloud<pcl::PointXYZ>::Ptr rays_;
  pcl::KdTreeFLANN<pcl::PointXYZ> tree_;
  std::vector<int> idx_;
  std::vector<float> sq_;
};

}  // namespace

PoseScore ScorePose(const FeatureCloud& source, const ObjectTemplate& tmpl,
                    const Eigen::Matrix4f& object_T_camera, const RegistrationConfig& config,
                    bool with_covered) {
  const FeatureCloud::Ptr target = FrontFaces(tmpl, object_T_camera, config);
  pcl::KdTreeFLANN<FeaturePoint> tree;
  tree.setInputCloud(target);
  const auto k = static_cast<float>(config.chroma_dark_offset);
  const auto tol_sq = static_cast<float>(config.colour_tolerance * config.colour_tolerance);
  const Eigen::Affine3f T(object_T_camera);
  std::vector<int> idx;
  std::vector<float> sq;
  int geometric = 0, both = 0, covered = 0;
  std::optional<TemplateRays> rays;
  if (with_covered) rays.emplace(*target, T.inverse());
  for (const auto& sp : source.points) {
    FeaturePoint y;
    y.getVector3fMap() = T * sp.getVector3fMap();
    const auto radius = static_cast<float>(WidenedByDepthNoise(
        config.score_distance, sp.z, config.score_depth_sigmas, config.depth_noise));
    if (tree.radiusSearch(y, radius, idx, sq) <= 0) {
      if (rays && rays->covers(sp, static_cast<float>(config.score_distance) / sp.z)) ++covered;
      continue;
    }
    ++geometric;
    ++covered;
    const Eigen::Vector3f cs = Chroma(sp, k);
    for (int j : idx) {
      if ((Chroma((*target)[static_cast<std::size_t>(j)], k) - cs).squaredNorm() <= tol_sq) {
        ++both;
        break;
      }
    }
  }
  PoseScore s;
  const double n = static_cast<double>(std::max<std::size_t>(1, source.size()));
  s.geometric = geometric / n;
  s.colour = geometric > 0 ? static_cast<double>(both) / geometric : 0.0;
  s.score = both / n;
  s.covered = rays && covered > 0 ? static_cast<double>(geometric) / covered : 0.0;
  return s;
}

bool ShapeAgrees(const PoseScore& s, const RegistrationConfig& config) {
  return s.geometric >= config.min_geometric_agreement ||
         (s.covered >= config.min_covered_agreement &&
          s.geometric >= config.min_geometric_agreement_covered);
}

}  // namespace moslam::pose_detail
