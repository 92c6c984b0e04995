#include "moslam/pose_estimation/segmentation.h"

#include <pcl/features/integral_image_normal.h>
#include <pcl/segmentation/euclidean_cluster_comparator.h>
#include <pcl/segmentation/organized_connected_component_segmentation.h>
#include <pcl/segmentation/organized_multi_plane_segmentation.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <set>
#include <string>

#include "moslam/common/errors.h"

namespace moslam {
namespace {

// pcl::EuclideanClusterComparator with the threshold of SegmentationConfig::cluster_distance:
// widened by the depth noise at the first pixel's depth. The label test is PCL's (two points join
// only if both labels are in the exclude set).
class DepthNoiseClusterComparator
    : public pcl::EuclideanClusterComparator<OrganizedPoint, pcl::Label> {
 public:
  DepthNoiseClusterComparator(float distance, const AxialDepthNoise& noise, double sigmas)
      : distance_sq_(static_cast<double>(distance) * distance),
        noise_(noise),
        sigmas_(sigmas * std::sqrt(2.0)) {}

  bool compare(int idx1, int idx2) const override {
    if (labels_ && exclude_labels_) {
      if (exclude_labels_->count((*labels_)[idx1].label) == 0) return false;
      if (exclude_labels_->count((*labels_)[idx2].label) == 0) return false;
    }
    const OrganizedPoint& p = (*input_)[idx1];
    const double widen = sigmas_ * noise_.sigma(p.z);
    const double d2 = (p.getVector3fMap() - (*input_)[idx2].getVector3fMap()).squaredNorm();
    return d2 < distance_sq_ + widen * widen;
  }

 private:
  double distance_sq_;
  AxialDepthNoise noise_;
  double sigmas_;
};

constexpr double kDegToRad = 3.14159265358979323846 / 180.0;

double MsSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

void Require(bool ok, const std::string& field, const std::string& what) {
  if (!ok) throw InvalidInputError("SegmentationConfig." + field + " " + what);
}

// Integer pixel bounds [u0, u1) x [v0, v1) of a box clipped to the image.
struct PixelBox {
  int u0 = 0, v0 = 0, u1 = 0, v1 = 0;
  bool empty() const { return u1 <= u0 || v1 <= v0; }
  bool contains(int u, int v) const { return u >= u0 && u < u1 && v >= v0 && v < v1; }
};

PixelBox Clip(const cv::Rect2f& box, int width, int height) {
  // Pixel centres at integer coordinates: pixel u is inside if box.x <= u < box.x + width.
  PixelBox b;
  b.u0 = std::max(0, static_cast<int>(std::ceil(box.x)));
  b.v0 = std::max(0, static_cast<int>(std::ceil(box.y)));
  b.u1 = std::min(width, static_cast<int>(std::ceil(box.x + box.width)));
  b.v1 = std::min(height, static_cast<int>(std::ceil(box.y + box.height)));
  return b;
}

cv::Rect2f Grow(const cv::Rect2f& box, double fraction) {
  const float dx = static_cast<float>(fraction) * box.width;
  const float dy = static_cast<float>(fraction) * box.height;
  return cv::Rect2f(box.x - dx, box.y - dy, box.width + 2.0f * dx, box.height + 2.0f * dy);
}

bool Finite(const OrganizedPoint& p) {
  return std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z);
}

}  // namespace

void SegmentationConfig::validate() const {
  Require(std::isfinite(normal_max_depth_change_factor) && normal_max_depth_change_factor > 0.0f,
          "normal_max_depth_change_factor", "must be positive");
  Require(std::isfinite(normal_smoothing_size) && normal_smoothing_size >= 1.0f,
          "normal_smoothing_size", "must be >= 1 pixel");
  Require(min_plane_inliers >= 3, "min_plane_inliers", "must be >= 3");
  Require(std::isfinite(plane_angular_threshold_deg) && plane_angular_threshold_deg > 0.0 &&
              plane_angular_threshold_deg < 90.0,
          "plane_angular_threshold_deg", "must be in (0, 90)");
  Require(std::isfinite(plane_distance_threshold) && plane_distance_threshold > 0.0,
          "plane_distance_threshold", "must be positive");
  Require(std::isfinite(plane_max_curvature) && plane_max_curvature > 0.0, "plane_max_curvature",
          "must be positive");
  Require(std::isfinite(box_margin_fraction) && box_margin_fraction >= 0.0, "box_margin_fraction",
          "must be >= 0");
  Require(std::isfinite(structural_outside_fraction) && structural_outside_fraction >= 0.0 &&
              structural_outside_fraction < 1.0,
          "structural_outside_fraction", "must be in [0, 1)");
  Require(up_in_camera.allFinite() && std::abs(up_in_camera.norm() - 1.0) < 1e-6, "up_in_camera",
          "must be a unit vector");
  Require(std::isfinite(camera_height), "camera_height", "must be finite");
  Require(std::isfinite(floor_height_tolerance) && floor_height_tolerance >= 0.0,
          "floor_height_tolerance", "must be >= 0");
  Require(std::isfinite(floor_max_tilt_deg) && floor_max_tilt_deg >= 0.0 &&
              floor_max_tilt_deg < 90.0,
          "floor_max_tilt_deg", "must be in [0, 90)");
  Require(std::isfinite(structure_normal_tolerance_deg) && structure_normal_tolerance_deg >= 0.0 &&
              structure_normal_tolerance_deg <= 90.0,
          "structure_normal_tolerance_deg", "must be in [0, 90]");
  Require(std::isfinite(cluster_distance) && cluster_distance > 0.0f, "cluster_distance",
          "must be positive");
  depth_noise.validate("SegmentationConfig.depth_noise.");
  Require(std::isfinite(cluster_depth_sigmas) && cluster_depth_sigmas >= 0.0,
          "cluster_depth_sigmas", "must be >= 0");
  Require(min_segment_points >= 1, "min_segment_points", "must be >= 1");
  Require(std::isfinite(tie_ratio) && tie_ratio > 0.0 && tie_ratio <= 1.0, "tie_ratio",
          "must be in (0, 1]");
  smoothing.validate("SegmentationConfig.smoothing.");
}

const char* ToString(SegmentationStatus status) {
  switch (status) {
    case SegmentationStatus::kOk: return "ok";
    case SegmentationStatus::kEmptyBox: return "empty_box";
    case SegmentationStatus::kTooFewPoints: return "too_few_points";
    case SegmentationStatus::kNoCluster: return "no_cluster";
  }
  return "unknown";
}

PreparedFrame PrepareSegmentation(const OrganizedCloud::ConstPtr& cloud,
                                  const SegmentationConfig& config) {
  config.validate();
  if (!cloud || !cloud->isOrganized() || cloud->width < 3 || cloud->height < 3) {
    throw InvalidInputError("PrepareSegmentation: the cloud must be organized (height > 1)");
  }
  PreparedFrame out;
  out.cloud = cloud;

  auto t0 = std::chrono::steady_clock::now();
  auto normals = std::make_shared<pcl::PointCloud<pcl::Normal>>();
  pcl::IntegralImageNormalEstimation<OrganizedPoint, pcl::Normal> ne;
  ne.setNormalEstimationMethod(ne.COVARIANCE_MATRIX);
  ne.setMaxDepthChangeFactor(config.normal_max_depth_change_factor);
  ne.setNormalSmoothingSize(config.normal_smoothing_size);
  ne.setInputCloud(cloud);
  ne.compute(*normals);
  out.normals = normals;
  out.normals_ms = MsSince(t0);

  t0 = std::chrono::steady_clock::now();
  pcl::OrganizedMultiPlaneSegmentation<OrganizedPoint, pcl::Normal, pcl::Label> mps;
  mps.setMinInliers(static_cast<unsigned>(config.min_plane_inliers));
  mps.setAngularThreshold(config.plane_angular_threshold_deg * kDegToRad);
  mps.setDistanceThreshold(config.plane_distance_threshold);
  mps.setMaximumCurvature(config.plane_max_curvature);
  mps.setInputNormals(normals);
  mps.setInputCloud(cloud);
  std::vector<pcl::ModelCoefficients> coefficients;
  std::vector<pcl::PointIndices> inliers;
  mps.segment(coefficients, inliers);
  for (std::size_t i = 0; i < coefficients.size() && i < inliers.size(); ++i) {
    const auto& c = coefficients[i].values;
    if (c.size() != 4) continue;
    Eigen::Vector4d q(c[0], c[1], c[2], c[3]);
    const double n = q.head<3>().norm();
    if (!(n > 0.0) || !q.allFinite()) continue;
    ScenePlane plane;
    plane.coefficients = q / n;
    plane.inliers.assign(inliers[i].indices.begin(), inliers[i].indices.end());
    out.planes.push_back(std::move(plane));
  }
  out.planes_ms = MsSince(t0);
  return out;
}

bool IsStructuralPlane(const ScenePlane& plane, std::size_t cloud_width, const cv::Rect2f& box,
                       const SegmentationConfig& config) {
  return ClassifyPlane(plane, cloud_width, box, config) != PlaneRole::kObject;
}

PlaneRole ClassifyPlane(const ScenePlane& plane, std::size_t cloud_width, const cv::Rect2f& box,
                        const SegmentationConfig& config) {
  if (plane.inliers.empty()) return PlaneRole::kObject;
  // (b) the floor: horizontal, at floor height below the camera.
  if (config.drop_floor) {
    Vector3 n = plane.coefficients.head<3>();
    double d = plane.coefficients[3];
    if (n.dot(config.up_in_camera) < 0.0) {
      n = -n;
      d = -d;
    }
    // Points on the plane satisfy n.p = -d; with n ~ up, -d is the plane's height above the
    // camera, so a floor at camera_height below the camera has d ~ camera_height.
    const bool horizontal = n.dot(config.up_in_camera) >= std::cos(config.floor_max_tilt_deg *
                                                                   kDegToRad);
    if (horizontal && std::abs(d - config.camera_height) <= config.floor_height_tolerance) {
      return PlaneRole::kFloor;
    }
  }
  // (a) extends well outside the grown box.
  const cv::Rect2f grown = Grow(box, config.box_margin_fraction);
  std::size_t outside = 0;
  for (int index : plane.inliers) {
    const Eigen::Vector2i uv = PixelOfIndex(static_cast<std::size_t>(index), cloud_width);
    const float u = static_cast<float>(uv.x()), v = static_cast<float>(uv.y());
    if (u < grown.x || u >= grown.x + grown.width || v < grown.y || v >= grown.y + grown.height) {
      ++outside;
    }
  }
  return static_cast<double>(outside) >
                 config.structural_outside_fraction * static_cast<double>(plane.inliers.size())
             ? PlaneRole::kOutsideBox
             : PlaneRole::kObject;
}

SegmentationResult SegmentObject(const PreparedFrame& frame, const cv::Rect2f& box,
                                 const SegmentationConfig& config) {
  return SegmentObject(frame, box, config, {});
}

namespace {

using LabelCloud = pcl::PointCloud<pcl::Label>;

// The comparator's labels (header comment, steps 3-4): 0 = candidate (valid, inside the grown box
// `outer`, neither claimed nor structure), 1 = everything else. Counts in `result` the claimed and
// the structure points inside the box `inner`, and the planes dropped.
std::shared_ptr<LabelCloud> CandidateLabels(const PreparedFrame& frame, const cv::Rect2f& box,
                                            const PixelBox& inner, const PixelBox& outer,
                                            const SegmentationConfig& config,
                                            const std::vector<int>& claimed,
                                            SegmentationResult& result) {
  const OrganizedCloud& cloud = *frame.cloud;
  const int width = static_cast<int>(cloud.width);
  pcl::Label one;
  one.label = 1;
  auto labels = std::make_shared<LabelCloud>(cloud.width, cloud.height, one);
  for (int v = outer.v0; v < outer.v1; ++v) {
    for (int u = outer.u0; u < outer.u1; ++u) {
      if (Finite(cloud.at(u, v))) (*labels)[static_cast<std::size_t>(v * width + u)].label = 0;
    }
  }
  for (int index : claimed) {
    if (index < 0 || static_cast<std::size_t>(index) >= labels->size()) {
      throw InvalidInputError("SegmentObject: a claimed pixel index lies outside the cloud");
    }
    auto& l = (*labels)[static_cast<std::size_t>(index)];
    if (l.label != 0) continue;
    const Eigen::Vector2i uv = PixelOfIndex(static_cast<std::size_t>(index), cloud.width);
    if (inner.contains(uv.x(), uv.y())) ++result.claimed_points_in_box;
    l.label = 1;
  }
  const double cos_normal = std::cos(config.structure_normal_tolerance_deg * kDegToRad);
  for (const ScenePlane& plane : frame.planes) {
    const PlaneRole role = ClassifyPlane(plane, cloud.width, box, config);
    if (role == PlaneRole::kObject) continue;
    ++result.planes_dropped;
    auto drop = [&](std::size_t i) {
      auto& l = (*labels)[i];
      if (l.label != 0) return;
      const Eigen::Vector2i uv = PixelOfIndex(i, cloud.width);
      if (inner.contains(uv.x(), uv.y())) ++result.structure_points_in_box;
      l.label = 1;
    };
    for (int index : plane.inliers) drop(static_cast<std::size_t>(index));
    // Near-plane points that missed the inlier set (see the header comment).
    const Eigen::Vector3f n = plane.coefficients.head<3>().cast<float>();
    const auto d = static_cast<float>(plane.coefficients[3]);
    const auto max_distance = static_cast<float>(config.plane_distance_threshold);
    for (int v = outer.v0; v < outer.v1; ++v) {
      for (int u = outer.u0; u < outer.u1; ++u) {
        const auto i = static_cast<std::size_t>(v * width + u);
        if ((*labels)[i].label != 0) continue;
        if (std::abs(n.dot(cloud[i].getVector3fMap()) + d) > max_distance) continue;
        if (role == PlaneRole::kOutsideBox) {
          const pcl::Normal& pn = (*frame.normals)[i];
          const Eigen::Vector3f m(pn.normal_x, pn.normal_y, pn.normal_z);
          if (m.allFinite() && std::abs(m.dot(n)) < cos_normal * m.norm()) continue;
        }
        drop(i);
      }
    }
  }
  return labels;
}

// Connected components of the candidate points (header comment, step 4).
std::vector<pcl::PointIndices> Components(const PreparedFrame& frame,
                                          const std::shared_ptr<LabelCloud>& labels,
                                          const SegmentationConfig& config) {
  auto comparator = std::make_shared<DepthNoiseClusterComparator>(
      config.cluster_distance, config.depth_noise, config.cluster_depth_sigmas);
  comparator->setInputCloud(frame.cloud);
  comparator->setLabels(labels);
  comparator->setExcludeLabels(
      std::make_shared<const std::set<std::uint32_t>>(std::set<std::uint32_t>{0}));
  pcl::OrganizedConnectedComponentSegmentation<OrganizedPoint, pcl::Label> occ(comparator);
  occ.setInputCloud(frame.cloud);
  LabelCloud components;
  std::vector<pcl::PointIndices> component_indices;
  occ.segment(components, component_indices);
  return component_indices;
}

struct Candidate {
  std::size_t component;
  int in_box;
  double mean_z;
  double box_iou;  // of the component's pixel bounding box with the detection box
  int count;       // points in the grown box
};

// The components with points inside the box `inner`, each with what the selection weighs.
std::vector<Candidate> Candidates(const OrganizedCloud& cloud, const LabelCloud& labels,
                                  const std::vector<pcl::PointIndices>& component_indices,
                                  const cv::Rect2f& box, const PixelBox& inner) {
  const int width = static_cast<int>(cloud.width), height = static_cast<int>(cloud.height);
  const double box_area = static_cast<double>(box.width) * box.height;
  std::vector<Candidate> candidates;
  for (std::size_t c = 0; c < component_indices.size(); ++c) {
    int in_box = 0;
    double sum_z = 0.0;
    int count = 0;
    int u0 = width, v0 = height, u1 = -1, v1 = -1;
    for (auto index : component_indices[c].indices) {
      const auto i = static_cast<std::size_t>(index);
      if (labels[i].label != 0) continue;  // singleton runs of excluded points
      const Eigen::Vector2i uv = PixelOfIndex(i, cloud.width);
      if (inner.contains(uv.x(), uv.y())) ++in_box;
      u0 = std::min(u0, uv.x());
      v0 = std::min(v0, uv.y());
      u1 = std::max(u1, uv.x() + 1);
      v1 = std::max(v1, uv.y() + 1);
      sum_z += static_cast<double>(cloud[i].z);
      ++count;
    }
    if (in_box == 0) continue;
    const cv::Rect2f extent(static_cast<float>(u0), static_cast<float>(v0),
                            static_cast<float>(u1 - u0), static_cast<float>(v1 - v0));
    const double inter = (extent & box).area();
    const double uni = box_area + extent.area() - inter;
    candidates.push_back({c, in_box, sum_z / count, uni > 0.0 ? inter / uni : 0.0, count});
  }
  return candidates;
}

// The object's component (header comment, step 5), or null when none holds min_segment_points
// inside the box.
const Candidate* SelectComponent(const std::vector<Candidate>& candidates,
                                 const SegmentationConfig& config) {
  int best_count = 0;
  for (const auto& c : candidates) best_count = std::max(best_count, c.in_box);
  if (best_count < config.min_segment_points) return nullptr;
  const Candidate* best = nullptr;
  if (config.selection == ComponentSelection::kBoxFit) {
    // The fit to the box times the share inside it; ties: more points.
    auto key = [](const Candidate& c) {
      return std::make_pair(c.box_iou * c.in_box / c.count, c.in_box);
    };
    for (const auto& c : candidates) {
      if (c.in_box < config.min_segment_points) continue;
      if (best == nullptr || key(c) > key(*best)) best = &c;
    }
  } else {
    for (const auto& c : candidates) {
      if (c.in_box < config.min_segment_points ||
          static_cast<double>(c.in_box) < config.tie_ratio * best_count) {
        continue;
      }
      if (best == nullptr || c.mean_z < best->mean_z) best = &c;
    }
  }
  return best;
}

}  // namespace

SegmentationResult SegmentObject(const PreparedFrame& frame, const cv::Rect2f& box,
                                 const SegmentationConfig& config,
                                 const std::vector<int>& claimed) {
  config.validate();
  if (!std::isfinite(box.x) || !std::isfinite(box.y) || !std::isfinite(box.width) ||
      !std::isfinite(box.height) || box.width < 0.0f || box.height < 0.0f) {
    throw InvalidInputError("SegmentObject: the box must be finite with non-negative size");
  }
  if (!frame.cloud || !frame.cloud->isOrganized()) {
    throw InvalidInputError("SegmentObject: the frame was not prepared (no organized cloud)");
  }
  const auto t0 = std::chrono::steady_clock::now();
  const OrganizedCloud& cloud = *frame.cloud;
  const int width = static_cast<int>(cloud.width), height = static_cast<int>(cloud.height);
  SegmentationResult result;
  const PixelBox inner = Clip(box, width, height);
  const PixelBox outer = Clip(Grow(box, config.box_margin_fraction), width, height);
  const auto done = [&](SegmentationStatus status) {
    result.status = status;
    result.time_ms = MsSince(t0);
    return result;
  };

  if (!inner.empty()) {
    for (int v = inner.v0; v < inner.v1; ++v) {
      for (int u = inner.u0; u < inner.u1; ++u) {
        if (Finite(cloud.at(u, v))) ++result.valid_points_in_box;
      }
    }
  }
  if (result.valid_points_in_box == 0) return done(SegmentationStatus::kEmptyBox);

  const std::shared_ptr<LabelCloud> labels =
      CandidateLabels(frame, box, inner, outer, config, claimed, result);
  if (result.valid_points_in_box - result.structure_points_in_box - result.claimed_points_in_box <
      config.min_segment_points) {
    return done(SegmentationStatus::kTooFewPoints);
  }
  const std::vector<pcl::PointIndices> components = Components(frame, labels, config);
  const std::vector<Candidate> candidates = Candidates(cloud, *labels, components, box, inner);
  result.components = static_cast<int>(candidates.size());
  const Candidate* best = SelectComponent(candidates, config);
  if (best == nullptr) return done(SegmentationStatus::kNoCluster);

  for (auto index : components[best->component].indices) {
    const auto i = static_cast<std::size_t>(index);
    if ((*labels)[i].label == 0) result.indices.push_back(static_cast<int>(i));
  }
  if (config.smoothing.enabled) {  // the segment's points, copied once
    result.segment = SmoothAlongRays(cloud, result.indices, config.depth_noise, config.smoothing);
  } else {
    result.segment = std::make_shared<OrganizedCloud>();
    result.segment->reserve(result.indices.size());
    for (int i : result.indices) result.segment->push_back(cloud[static_cast<std::size_t>(i)]);
    result.segment->is_dense = true;
  }
  return done(SegmentationStatus::kOk);
}

}  // namespace moslam
