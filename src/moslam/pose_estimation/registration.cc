// The one heavy translation unit of the front-end: PFHRGB, SAC-IA and GICP template
// instantiations (~40 s, ~1.4 GB to compile; shared/notes/frontend.md pitfall 4).
#include "moslam/pose_estimation/registration.h"

#include <pcl/common/transforms.h>
#include <pcl/features/normal_3d.h>
#include <pcl/features/pfhrgb.h>
#include <pcl/filters/voxel_grid.h>
#include <pcl/kdtree/kdtree_flann.h>
#include <pcl/registration/gicp.h>
#include <pcl/registration/ia_ransac.h>
#include <pcl/registration/sample_consensus_prerejective.h>
#include <pcl/search/kdtree.h>

#include <Eigen/Dense>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "moslam/common/errors.h"
#include "moslam/pose_estimation/feature_index.h"
#include "moslam/pose_estimation/pose_hypotheses.h"
#include "moslam/pose_estimation/pose_information.h"
#include "moslam/pose_estimation/pose_score.h"
#include "moslam/render/rgbd.h"

namespace moslam {
namespace {

using pose_detail::FrontFaces;
using pose_detail::PoseScore;
using pose_detail::ScorePose;
using pose_detail::ShapeAgrees;
using pose_detail::SymmetryHypotheses;
using pose_detail::UprightHypotheses;
using pose_detail::WidenedByDepthNoise;

double MsSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

bool PositiveFinite(double x) { return std::isfinite(x) && x > 0.0; }

void Require(bool ok, const std::string& field, const std::string& what) {
  if (!ok) throw InvalidInputError(field + " " + what);
}

// The consensus' inlier distance: sac_max_correspondence_distance widened at the median depth of
// the segment's keypoints (one radius per segment: the consensus counts on one grid). `keypoints`
// is not empty.
double ConsensusDistance(const FeatureCloud& keypoints, const RegistrationConfig& config) {
  std::vector<float> depths;
  depths.reserve(keypoints.size());
  for (const FeaturePoint& p : keypoints.points) depths.push_back(p.z);
  const auto middle = depths.begin() + static_cast<std::ptrdiff_t>(depths.size() / 2);
  std::nth_element(depths.begin(), middle, depths.end());
  return WidenedByDepthNoise(config.sac_max_correspondence_distance, *middle,
                             config.consensus_depth_sigmas, config.depth_noise);
}

bool FiniteFeature(const pcl::PFHRGBSignature250& f) {
  for (float h : f.histogram) {
    if (!std::isfinite(h)) return false;
  }
  return true;
}

// At most `max_points` of `cloud`, evenly strided (the cloud itself when it is small enough or
// max_points is 0).
FeatureCloud::Ptr Subsample(const FeatureCloud::Ptr& cloud, int max_points) {
  const std::size_t n = cloud->size();
  if (max_points <= 0 || n <= static_cast<std::size_t>(max_points)) return cloud;
  const auto cap = static_cast<std::size_t>(max_points);
  auto out = std::make_shared<FeatureCloud>();
  out->reserve(cap);
  for (std::size_t j = 0; j < cap; ++j) out->push_back((*cloud)[j * n / cap]);
  return out;
}

SE3 ToSE3(const Eigen::Matrix4f& T) {
  const Eigen::Matrix4d M = T.cast<double>();
  return SE3(SO3::FromMatrixNormalized(M.topLeftCorner<3, 3>()), M.topRightCorner<3, 1>());
}

using Gicp = pcl::GeneralizedIterativeClosestPoint<FeaturePoint, FeaturePoint>;

// GICP's plane model taken from the points' unit normals: C = R diag(1, 1, epsilon) R^T with the
// normal as R's last column, i.e. I - (1 - epsilon) n n^T. PCL estimates the same matrices from
// the 20 nearest neighbours at every align(); the normals are already there (the template's exact,
// the segment's estimated), and on thin parts (a chair's seat) neighbours from the far side bend
// PCL's estimate, never the normal.
Gicp::MatricesVectorPtr PlaneCovariances(const FeatureCloud& cloud, double epsilon = 1e-3) {
  auto out = std::make_shared<Gicp::MatricesVector>();
  out->reserve(cloud.size());
  for (const FeaturePoint& p : cloud.points) {
    const Eigen::Vector3d n = p.getNormalVector3fMap().cast<double>();
    out->push_back(Eigen::Matrix3d::Identity() - (1.0 - epsilon) * n * n.transpose());
  }
  return out;
}

// Which points of space lie within `radius` of some target point, on a grid of cells of
// radius / 3 (a cell is marked when its centre is within radius of a target point, so the test is
// exact to half a cell diagonal, 0.29 radius). Counting a hypothesis' inliers is then one
// transform and one lookup per point, against a k-d tree search per point in PCL's getFitness
// (measured 2.5 ms per hypothesis on a 700-keypoint chair segment: SAC-IA's whole cost).
class InlierGrid {
 public:
  InlierGrid(const FeatureCloud& target, float radius) : cell_(radius / 3.0f) {
    if (target.empty()) return;  // nothing is an inlier
    Eigen::Vector3f lo = Eigen::Vector3f::Constant(std::numeric_limits<float>::max());
    Eigen::Vector3f hi = -lo;
    for (const auto& p : target.points) {
      lo = lo.cwiseMin(p.getVector3fMap());
      hi = hi.cwiseMax(p.getVector3fMap());
    }
    // A template tens of metres wide would need billions of cells: coarser cells then (the test
    // loosens to half their diagonal), at most 2^26 of them.
    for (;;) {
      double cells = 1.0;
      for (int a = 0; a < 3; ++a) {
        cells *= std::ceil((hi[a] - lo[a] + 2.0f * (radius + cell_)) / cell_);
      }
      if (cells <= static_cast<double>(1 << 26)) break;
      cell_ *= 2.0f;
    }
    origin_ = lo - Eigen::Vector3f::Constant(radius + cell_);
    for (int a = 0; a < 3; ++a) {
      size_[a] = static_cast<int>(std::ceil((hi[a] - lo[a] + 2.0f * (radius + cell_)) / cell_));
    }
    marked_.assign(static_cast<std::size_t>(size_[0]) * size_[1] * size_[2], 0);
    const int reach = static_cast<int>(std::ceil(radius / cell_));
    const float r2 = radius * radius;
    for (const auto& p : target.points) {
      const Eigen::Vector3f q = p.getVector3fMap();
      const Eigen::Vector3i c = cellOf(q);
      for (int i = -reach; i <= reach; ++i) {
        for (int j = -reach; j <= reach; ++j) {
          for (int k = -reach; k <= reach; ++k) {
            const Eigen::Vector3i n = c + Eigen::Vector3i(i, j, k);
            if (!inside(n)) continue;
            const Eigen::Vector3f centre =
                origin_ + (n.cast<float>() + Eigen::Vector3f::Constant(0.5f)) * cell_;
            if ((centre - q).squaredNorm() <= r2) marked_[index(n)] = 1;
          }
        }
      }
    }
  }

  int count(const FeatureCloud& source, const Eigen::Matrix4f& T) const {
    if (marked_.empty()) return 0;
    const Eigen::Matrix3f R = T.topLeftCorner<3, 3>();
    const Eigen::Vector3f t = T.topRightCorner<3, 1>();
    int n = 0;
    for (const auto& p : source.points) {
      const Eigen::Vector3i c = cellOf(R * p.getVector3fMap() + t);
      n += inside(c) && marked_[index(c)];
    }
    return n;
  }

 private:
  Eigen::Vector3i cellOf(const Eigen::Vector3f& q) const {
    return ((q - origin_) / cell_).array().floor().cast<int>();
  }
  bool inside(const Eigen::Vector3i& c) const {
    return (c.array() >= 0).all() && c[0] < size_[0] && c[1] < size_[1] && c[2] < size_[2];
  }
  std::size_t index(const Eigen::Vector3i& c) const {
    return (static_cast<std::size_t>(c[2]) * size_[1] + c[1]) * size_[0] + c[0];
  }

  float cell_;
  Eigen::Vector3f origin_ = Eigen::Vector3f::Zero();
  int size_[3] = {0, 0, 0};
  std::vector<unsigned char> marked_;
};

// pcl::SampleConsensusPrerejective's polygon pre-rejection inside RANSAC with its own criterion
// and random numbers:
//  - a sample is 3 segment keypoints, pairwise at least the minimum sample distance apart (as
//    SAC-IA's), each matched to one of its k nearest template features (k-NN computed once per
//    keypoint and kept: nearestFeatures());
//  - a sample whose triangle and its matches' are not similar (PCL's rejector) is dropped before
//    any point is transformed;
//  - of the others, the pose putting the MOST segment keypoints within the correspondence
//    distance of the template keypoints wins (counted on an InlierGrid; ties: the earlier).
// PCL's class keeps the lowest mean squared inlier distance among the poses above the inlier
// fraction instead, which on partial views of chairs prefers a tight fit of a few points (a flip,
// a 40-degree twist) to the right pose (measured: 2 of 8 rendered chair views against 7 of 8).
// Random numbers come from a std::mt19937 seeded by setSeed, not rand(): the result depends on
// the seed only, and registrations may run on several threads at once.
// converged_ iff the winner has at least inlier_fraction_ of the keypoints; inliers_ and the
// fitness are then PCL's exact ones for the winner.
class MaxInlierPrerejective
    : public pcl::SampleConsensusPrerejective<FeaturePoint, FeaturePoint,
                                              pcl::PFHRGBSignature250> {
 public:
  void setMinSampleDistance(float d) { min_sample_distance_sq_ = d * d; }
  void setSeed(unsigned seed) { rng_.seed(seed); }
  // The template's descriptors with a k-d tree already built on them (PCL's setTargetFeatures
  // builds one at every call).
  void setTargetFeatures(const PfhrgbCloud::ConstPtr& features,
                         const TemplateFeatureIndex::Tree::Ptr& tree) {
    target_features_ = features;
    feature_tree_ = tree;
  }
  // Per segment keypoint, its k nearest template features (empty if never sampled).
  const std::vector<pcl::Indices>& nearestFeatures() const { return similar_; }

 protected:
  void computeTransformation(pcl::PointCloud<FeaturePoint>& output,
                             const Eigen::Matrix4f& guess) override {
    correspondence_rejector_poly_->setInputSource(input_);
    correspondence_rejector_poly_->setInputTarget(target_);
    correspondence_rejector_poly_->setCardinality(nr_samples_);
    const InlierGrid grid(*target_, static_cast<float>(corr_dist_threshold_));
    final_transformation_ = guess;
    inliers_.clear();
    converged_ = false;
    const int n_source = static_cast<int>(input_->size());
    if (n_source < nr_samples_) return;
    similar_.assign(input_->size(), {});
    std::uniform_int_distribution<int> pick_point(0, n_source - 1);
    std::uniform_int_distribution<int> pick_match(0, k_correspondences_ - 1);
    std::vector<float> distances;
    pcl::Indices sample(static_cast<std::size_t>(nr_samples_));
    pcl::Indices matches(sample.size());
    int best = 0;
    for (int i = 0; i < max_iterations_; ++i) {
      bool ok = true;
      for (std::size_t a = 0; a < sample.size() && ok; ++a) {
        sample[a] = pick_point(rng_);
        const Eigen::Vector3f pa = (*input_)[static_cast<std::size_t>(sample[a])].getVector3fMap();
        for (std::size_t b = 0; b < a && ok; ++b) {
          ok = (pa - (*input_)[static_cast<std::size_t>(sample[b])].getVector3fMap())
                   .squaredNorm() >= std::max(min_sample_distance_sq_, 1e-12f);
        }
      }
      if (!ok) continue;
      for (std::size_t a = 0; a < sample.size(); ++a) {
        pcl::Indices& knn = similar_[static_cast<std::size_t>(sample[a])];
        if (knn.empty()) {
          feature_tree_->nearestKSearch(*input_features_, sample[a], k_correspondences_, knn,
                                        distances);
        }
        if (knn.empty()) {
          ok = false;
          break;
        }
        matches[a] = knn[std::min<std::size_t>(static_cast<std::size_t>(pick_match(rng_)),
                                               knn.size() - 1)];
      }
      if (!ok || !correspondence_rejector_poly_->thresholdPolygon(sample, matches)) continue;
      transformation_estimation_->estimateRigidTransformation(*input_, sample, *target_, matches,
                                                              transformation_);
      const int n = grid.count(*input_, transformation_);
      if (n > best) {
        best = n;
        final_transformation_ = transformation_;
      }
    }
    if (best == 0) return;
    float error = 0.0f;
    getFitness(inliers_, error);  // exact, at final_transformation_
    converged_ = !inliers_.empty() && static_cast<float>(inliers_.size()) >=
                                          inlier_fraction_ * static_cast<float>(input_->size());
    if (converged_) pcl::transformPointCloud(*input_, output, final_transformation_);
  }

 private:
  float min_sample_distance_sq_ = 0.0f;
  std::mt19937 rng_{1u};
  std::vector<pcl::Indices> similar_;
};

}  // namespace

void FeatureConfig::validate() const {
  Require(PositiveFinite(voxel_size), "FeatureConfig.voxel_size", "must be positive");
  Require(PositiveFinite(normal_radius) && normal_radius > voxel_size,
          "FeatureConfig.normal_radius", "must be larger than voxel_size");
  Require(PositiveFinite(feature_radius) && feature_radius > voxel_size,
          "FeatureConfig.feature_radius", "must be larger than voxel_size");
  Require(std::isfinite(feature_surface_voxel) && feature_surface_voxel >= 0.0 &&
              feature_surface_voxel < feature_radius,
          "FeatureConfig.feature_surface_voxel", "must be >= 0 and smaller than feature_radius");
  Require(std::isfinite(keypoint_voxel) && keypoint_voxel >= 0.0, "FeatureConfig.keypoint_voxel",
          "must be >= 0");
}

void RegistrationConfig::validate() const {
  features.validate();
  const std::string p = "RegistrationConfig.";
  Require(sac_iterations >= 1, p + "sac_iterations", "must be >= 1");
  Require(prerejective_iterations >= 1, p + "prerejective_iterations", "must be >= 1");
  Require(std::isfinite(prerejective_similarity) && prerejective_similarity >= 0.0 &&
              prerejective_similarity < 1.0,
          p + "prerejective_similarity", "must be in [0, 1)");
  Require(std::isfinite(prerejective_inlier_fraction) && prerejective_inlier_fraction >= 0.0 &&
              prerejective_inlier_fraction <= 1.0,
          p + "prerejective_inlier_fraction", "must be in [0, 1]");
  Require(gicp_max_source_points == 0 || gicp_max_source_points >= min_segment_points,
          p + "gicp_max_source_points", "must be 0 (no cap) or >= min_segment_points");
  Require(gicp_coarse_points == 0 || gicp_coarse_points >= min_segment_points,
          p + "gicp_coarse_points", "must be 0 (no cap) or >= min_segment_points");
  Require(gicp_coarse_iterations >= 1, p + "gicp_coarse_iterations", "must be >= 1");
  Require(PositiveFinite(gicp_coarse_max_correspondence_distance),
          p + "gicp_coarse_max_correspondence_distance", "must be positive");
  Require(sac_correspondence_randomness >= 1, p + "sac_correspondence_randomness",
          "must be >= 1");
  Require(std::isfinite(sac_min_sample_distance) && sac_min_sample_distance >= 0.0,
          p + "sac_min_sample_distance", "must be >= 0");
  Require(PositiveFinite(sac_max_correspondence_distance), p + "sac_max_correspondence_distance",
          "must be positive");
  Require(PositiveFinite(inlier_distance), p + "inlier_distance", "must be positive");
  Require(min_inliers >= 3, p + "min_inliers", "must be >= 3 (a rigid transform needs 3)");
  Require(min_segment_points >= 3, p + "min_segment_points", "must be >= 3");
  Require(max_segment_keypoints == 0 || max_segment_keypoints >= min_inliers,
          p + "max_segment_keypoints", "must be 0 (no cap) or >= min_inliers");
  Require(gicp_max_iterations >= 1, p + "gicp_max_iterations", "must be >= 1");
  Require(PositiveFinite(gicp_max_correspondence_distance),
          p + "gicp_max_correspondence_distance", "must be positive");
  Require(PositiveFinite(gicp_transformation_epsilon), p + "gicp_transformation_epsilon",
          "must be positive");
  Require(symmetry_turns >= 1, p + "symmetry_turns", "must be >= 1");
  Require(upright_yaws >= 0, p + "upright_yaws", "must be >= 0");
  Require(std::isfinite(upright_min_extent) && upright_min_extent >= 0.0,
          p + "upright_min_extent", "must be >= 0");
  Require(camera_up.allFinite() && camera_up.norm() > 1e-6, p + "camera_up",
          "must be a finite non-zero vector");
  Require(PositiveFinite(score_distance), p + "score_distance", "must be positive");
  depth_noise.validate(p + "depth_noise.");
  Require(std::isfinite(score_depth_sigmas) && score_depth_sigmas >= 0.0,
          p + "score_depth_sigmas", "must be >= 0");
  Require(std::isfinite(inlier_depth_sigmas) && inlier_depth_sigmas >= 0.0,
          p + "inlier_depth_sigmas", "must be >= 0");
  Require(std::isfinite(consensus_depth_sigmas) && consensus_depth_sigmas >= 0.0,
          p + "consensus_depth_sigmas", "must be >= 0");
  Require(PositiveFinite(colour_tolerance), p + "colour_tolerance", "must be positive");
  Require(std::isfinite(chroma_dark_offset) && chroma_dark_offset >= 0.0,
          p + "chroma_dark_offset", "must be >= 0");
  Require(std::isfinite(min_geometric_agreement) && min_geometric_agreement >= 0.0 &&
              min_geometric_agreement <= 1.0,
          p + "min_geometric_agreement", "must be in [0, 1]");
  Require(std::isfinite(min_covered_agreement) && min_covered_agreement >= 0.0 &&
              min_covered_agreement <= 1.0,
          p + "min_covered_agreement", "must be in [0, 1]");
  Require(std::isfinite(min_geometric_agreement_covered) &&
              min_geometric_agreement_covered >= 0.0 && min_geometric_agreement_covered <= 1.0,
          p + "min_geometric_agreement_covered", "must be in [0, 1]");
  Require(std::isfinite(min_colour_agreement) && min_colour_agreement >= 0.0 &&
              min_colour_agreement <= 1.0,
          p + "min_colour_agreement", "must be in [0, 1]");
  Require(PositiveFinite(information_sigma_point), p + "information_sigma_point",
          "must be positive");
  Require(PositiveFinite(information_max_effective_points),
          p + "information_max_effective_points", "must be positive");
  Require(PositiveFinite(sigma_rotation_floor_deg), p + "sigma_rotation_floor_deg",
          "must be positive");
  Require(std::isfinite(information_floor_noise) && information_floor_noise >= 0.0,
          p + "information_floor_noise", "must be >= 0 (m; 0: fixed floors)");
  Require(PositiveFinite(sigma_translation_floor), p + "sigma_translation_floor",
          "must be positive");
}

const char* ToString(RegistrationStatus status) {
  switch (status) {
    case RegistrationStatus::kAccepted: return "accepted";
    case RegistrationStatus::kTooFewPoints: return "too_few_points";
    case RegistrationStatus::kTooFewInliers: return "too_few_inliers";
    case RegistrationStatus::kGicpFailed: return "gicp_failed";
    case RegistrationStatus::kColourMismatch: return "colour_mismatch";
    case RegistrationStatus::kShapeMismatch: return "shape_mismatch";
  }
  return "unknown";
}

namespace pose_detail {

FeatureCloud::Ptr VoxelDownsample(const FeatureCloud& cloud, double leaf,
                                  bool drop_degenerate_normals) {
  auto input = std::make_shared<FeatureCloud>(cloud);
  FeatureCloud voxelled;
  pcl::VoxelGrid<FeaturePoint> grid;
  const auto l = static_cast<float>(leaf);
  grid.setLeafSize(l, l, l);
  grid.setInputCloud(input);
  grid.filter(voxelled);
  auto out = std::make_shared<FeatureCloud>();
  out->reserve(voxelled.size());
  for (auto p : voxelled.points) {
    Eigen::Vector3f n(p.normal_x, p.normal_y, p.normal_z);
    const float norm = n.norm();
    if (drop_degenerate_normals && !(norm >= 0.1f)) continue;
    if (norm > 1e-6f) n /= norm;
    p.normal_x = n.x();
    p.normal_y = n.y();
    p.normal_z = n.z();
    out->push_back(p);
  }
  return out;
}

void EstimateNormals(FeatureCloud& cloud, double radius, const Vector3& viewpoint) {
  auto input = std::make_shared<FeatureCloud>(cloud);
  pcl::NormalEstimation<FeaturePoint, FeaturePoint> ne;
  ne.setInputCloud(input);
  ne.setSearchMethod(std::make_shared<pcl::search::KdTree<FeaturePoint>>());
  ne.setRadiusSearch(radius);
  ne.setViewPoint(static_cast<float>(viewpoint.x()), static_cast<float>(viewpoint.y()),
                  static_cast<float>(viewpoint.z()));
  ne.compute(cloud);  // writes normal_x/y/z and curvature, keeps xyz and rgb
}

FeatureCloud::Ptr PrepareSurface(const OrganizedCloud& segment, const FeatureConfig& config,
                                 std::size_t min_points) {
  FeatureCloud finite;
  finite.reserve(segment.size());
  for (const auto& q : segment.points) {
    if (!std::isfinite(q.x) || !std::isfinite(q.y) || !std::isfinite(q.z)) continue;
    FeaturePoint p;
    p.x = q.x;
    p.y = q.y;
    p.z = q.z;
    p.rgba = q.rgba;
    p.normal_x = p.normal_y = p.normal_z = 0.0f;
    p.curvature = 0.0f;
    finite.push_back(p);
  }
  FeatureCloud::Ptr source = VoxelDownsample(finite, config.voxel_size);
  if (source->size() < min_points) return source;
  EstimateNormals(*source, config.normal_radius, Vector3::Zero());
  auto with_normals = std::make_shared<FeatureCloud>();
  for (const auto& p : source->points) {
    if (std::isfinite(p.normal_x) && std::isfinite(p.normal_y) && std::isfinite(p.normal_z)) {
      with_normals->push_back(p);
    }
  }
  return with_normals;
}

FeatureCloud::Ptr Keypoints(const FeatureCloud& surface, double keypoint_voxel) {
  if (keypoint_voxel <= 0.0) return std::make_shared<FeatureCloud>(surface);
  return VoxelDownsample(surface, keypoint_voxel);
}

PfhrgbCloud::Ptr ComputePfhrgb(const FeatureCloud::Ptr& surface, FeatureCloud::Ptr& keypoints,
                               const FeatureConfig& config) {
  auto features = std::make_shared<PfhrgbCloud>();
  const FeatureCloud::Ptr search_surface =
      config.feature_surface_voxel > config.voxel_size
          ? VoxelDownsample(*surface, config.feature_surface_voxel, true)
          : surface;
  pcl::PFHRGBEstimation<FeaturePoint, FeaturePoint, pcl::PFHRGBSignature250> est;
  est.setInputCloud(keypoints);
  est.setSearchSurface(search_surface);
  est.setInputNormals(search_surface);
  est.setSearchMethod(std::make_shared<pcl::search::KdTree<FeaturePoint>>());
  est.setRadiusSearch(config.feature_radius);
  est.compute(*features);
  auto kept = std::make_shared<FeatureCloud>();
  auto kept_features = std::make_shared<PfhrgbCloud>();
  for (std::size_t i = 0; i < keypoints->size() && i < features->size(); ++i) {
    if (!FiniteFeature((*features)[i])) continue;
    kept->push_back((*keypoints)[i]);
    kept_features->push_back((*features)[i]);
  }
  keypoints = kept;
  return kept_features;
}

}  // namespace pose_detail

bool PassesInlierGate(int consensus_inliers, int hypothesis, int refined_inliers,
                      int min_inliers) {
  if (refined_inliers >= min_inliers) return true;
  return hypothesis == 0 && consensus_inliers >= min_inliers;
}

SE3 ObjectMeasurementInBody(const SE3& camera_T_object) {
  return BodyFromCamera() * camera_T_object;
}

namespace {

// A search handle on the template's feature index; a template assembled by hand (no index, or
// one of other features) gets one built here.
TemplateFeatureIndex::Tree::Ptr FeatureTree(const ObjectTemplate& tmpl, float epsilon) {
  if (tmpl.feature_index && tmpl.feature_index->features() == tmpl.features.get()) {
    return tmpl.feature_index->tree(epsilon);
  }
  return TemplateFeatureIndex(tmpl.features).tree(epsilon);
}

void CheckInputs(const ObjectTemplate& tmpl, const RegistrationConfig& config) {
  config.validate();
  if (!tmpl.cloud || !tmpl.keypoints || !tmpl.features || tmpl.cloud->empty() ||
      tmpl.keypoints->empty() || tmpl.keypoints->size() != tmpl.features->size()) {
    throw InvalidInputError("RegisterTemplate: template '" + tmpl.label +
                            "' is empty (no points or keypoints) or its features do not match "
                            "its keypoints");
  }
  if (!(tmpl.config == config.features)) {
    throw InvalidInputError("RegisterTemplate: template '" + tmpl.label +
                            "' was built with a different FeatureConfig than "
                            "RegistrationConfig.features");
  }
}

// Finite points of the segment, voxelled, with normals (points without a normal dropped).
FeatureCloud::Ptr PrepareSegmentCloud(const OrganizedCloud& segment,
                                      const RegistrationConfig& config) {
  return pose_detail::PrepareSurface(segment, config.features,
                                     static_cast<std::size_t>(config.min_segment_points));
}

struct GicpOutcome {
  bool ok = false;
  Eigen::Matrix4f object_T_camera = Eigen::Matrix4f::Identity();
  double fitness = 0.0;
  FeatureCloud::Ptr target;  // the front-facing template points GICP aligned to
};

// The segment as GICP sees it: at most gicp_max_source_points (an evenly strided subset), with its
// covariances computed once for every hypothesis.
struct GicpSource {
  FeatureCloud::Ptr cloud;
  Gicp::MatricesVectorPtr covariances;
};

GicpSource MakeGicpSource(const FeatureCloud::Ptr& source, int max_points) {
  GicpSource out;
  out.cloud = Subsample(source, max_points);
  out.covariances = PlaneCovariances(*out.cloud);
  return out;
}

GicpOutcome RunGicp(const GicpSource& source, const ObjectTemplate& tmpl,
                    const Eigen::Matrix4f& object_T_camera_initial,
                    const RegistrationConfig& config, int max_iterations,
                    double max_correspondence_distance) {
  GicpOutcome out;
  out.target = FrontFaces(tmpl, object_T_camera_initial, config);
  Gicp gicp;
  gicp.setInputSource(source.cloud);
  gicp.setSourceCovariances(source.covariances);
  gicp.setInputTarget(out.target);
  gicp.setTargetCovariances(PlaneCovariances(*out.target));
  gicp.setMaximumIterations(max_iterations);
  gicp.setMaxCorrespondenceDistance(max_correspondence_distance);
  gicp.setTransformationEpsilon(config.gicp_transformation_epsilon);
  FeatureCloud refined;
  gicp.align(refined, object_T_camera_initial);
  out.object_T_camera = gicp.getFinalTransformation();
  out.ok = gicp.hasConverged() && out.object_T_camera.allFinite();
  if (out.ok) out.fitness = gicp.getFitnessScore(config.gicp_max_correspondence_distance);
  return out;
}

// GICP from each hypothesis, the best-scoring result kept (ties: the earlier hypothesis), the
// colour gate, then the information matrix; sets status, pose, fitness, scores, information and
// their times.
void RefineAndInform(const FeatureCloud::Ptr& source, const ObjectTemplate& tmpl,
                     const std::vector<Eigen::Matrix4f>& hypotheses,
                     const RegistrationConfig& config, RegistrationResult& result) {
  auto t0 = std::chrono::steady_clock::now();
  // Coarse pass (several hypotheses only): each hypothesis aligned with a small subset of the
  // segment and few iterations, scored on the whole segment; the best one is then refined.
  int start = 0;
  Eigen::Matrix4f initial = hypotheses.front();
  if (hypotheses.size() > 1) {
    const GicpSource coarse = MakeGicpSource(source, config.gicp_coarse_points);
    // Coarse poses are ranked on at most 1000 segment points (the winner is scored on all).
    const FeatureCloud::Ptr ranked = Subsample(source, 1000);
    double best_coarse = -1.0;
    start = -1;
    for (std::size_t h = 0; h < hypotheses.size(); ++h) {
      const GicpOutcome g =
          RunGicp(coarse, tmpl, hypotheses[h], config, config.gicp_coarse_iterations,
                  config.gicp_coarse_max_correspondence_distance);
      if (!g.ok) continue;
      const double score = ScorePose(*ranked, tmpl, g.object_T_camera, config).score;
      if (score > best_coarse) {
        best_coarse = score;
        start = static_cast<int>(h);
        initial = g.object_T_camera;
      }
    }
  }
  GicpOutcome best;
  PoseScore best_score;
  int best_index = -1;
  if (start >= 0) {
    GicpOutcome g = RunGicp(MakeGicpSource(source, config.gicp_max_source_points), tmpl, initial,
                            config, config.gicp_max_iterations,
                            config.gicp_max_correspondence_distance);
    if (g.ok) {
      best_score = ScorePose(*source, tmpl, g.object_T_camera, config, true);
      best = std::move(g);
      best_index = start;
    }
  }
  result.hypotheses = static_cast<int>(hypotheses.size());
  result.times.gicp = MsSince(t0);
  if (best_index < 0) {
    result.status = RegistrationStatus::kGicpFailed;
    return;
  }
  result.hypothesis = best_index;
  result.fitness = best.fitness;
  result.score = best_score.score;
  result.geometric_agreement = best_score.geometric;
  result.colour_agreement = best_score.colour;
  result.covered_agreement = best_score.covered;
  result.camera_T_object = ToSE3(best.object_T_camera).inverse();
  if (!ShapeAgrees(best_score, config)) {
    result.status = RegistrationStatus::kShapeMismatch;
    return;
  }
  if (best_score.colour < config.min_colour_agreement) {
    result.status = RegistrationStatus::kColourMismatch;
    return;
  }
  t0 = std::chrono::steady_clock::now();
  result.information =
      pose_detail::AlignmentInformation(*source, best.target, best.object_T_camera, config);
  result.times.information = MsSince(t0);
  result.status = RegistrationStatus::kAccepted;
}

}  // namespace

RegistrationResult RefinePose(const OrganizedCloud& segment, const ObjectTemplate& tmpl,
                              const SE3& initial_camera_T_object,
                              const RegistrationConfig& config) {
  CheckInputs(tmpl, config);
  RegistrationResult result;
  const auto t0 = std::chrono::steady_clock::now();
  const FeatureCloud::Ptr source = PrepareSegmentCloud(segment, config);
  result.segment_points = static_cast<int>(source->size());
  result.times.prepare = MsSince(t0);
  result.camera_T_object = initial_camera_T_object;
  if (result.segment_points < config.min_segment_points) {
    result.status = RegistrationStatus::kTooFewPoints;
    return result;
  }
  const Eigen::Matrix4f initial = initial_camera_T_object.inverse().matrix().cast<float>();
  RefineAndInform(source, tmpl, SymmetryHypotheses(*source, tmpl, initial, config), config, result);
  return result;
}

namespace {

// The template's feature search, built on first use: the prerejective consensus needs it, SAC-IA
// does not, and the gate only for keypoints the consensus matched to none.
class LazyFeatureTree {
 public:
  LazyFeatureTree(const ObjectTemplate& tmpl, float epsilon) : tmpl_(tmpl), epsilon_(epsilon) {}
  const TemplateFeatureIndex::Tree::Ptr& get() {
    if (!tree_) tree_ = FeatureTree(tmpl_, epsilon_);
    return tree_;
  }

 private:
  const ObjectTemplate& tmpl_;
  float epsilon_;
  TemplateFeatureIndex::Tree::Ptr tree_;
};

struct ConsensusOutcome {
  // False: no sampled pose put enough segment keypoints on the template (prerejective only);
  // then object_T_camera and fitness mean nothing.
  bool converged = true;
  Eigen::Matrix4f object_T_camera = Eigen::Matrix4f::Identity();
  double fitness = 0.0;
  std::vector<pcl::Indices> nearest_features;  // per keypoint, when the consensus has them
};

// The initial alignment, segment keypoints (camera frame) -> template keypoints (object frame),
// i.e. object_T_camera: SAC-IA or the max-inlier prerejective consensus.
ConsensusOutcome RunConsensus(const FeatureCloud::Ptr& keypoints, const PfhrgbCloud::Ptr& features,
                              const ObjectTemplate& tmpl, const RegistrationConfig& config,
                              double distance, LazyFeatureTree& tree) {
  ConsensusOutcome out;
  FeatureCloud aligned;
  if (config.consensus == Consensus::kSacIa) {
    std::srand(config.seed);  // PCL's SAC-IA draws with rand()
    pcl::SampleConsensusInitialAlignment<FeaturePoint, FeaturePoint, pcl::PFHRGBSignature250> sac;
    sac.setInputSource(keypoints);
    sac.setSourceFeatures(features);
    sac.setInputTarget(tmpl.keypoints);
    sac.setTargetFeatures(tmpl.features);
    sac.setNumberOfSamples(3);
    sac.setMinSampleDistance(static_cast<float>(config.sac_min_sample_distance));
    sac.setCorrespondenceRandomness(config.sac_correspondence_randomness);
    sac.setMaximumIterations(config.sac_iterations);
    sac.setMaxCorrespondenceDistance(distance);
    sac.align(aligned);
    out.object_T_camera = sac.getFinalTransformation();
    out.fitness = sac.getFitnessScore(distance);
    return out;
  }
  MaxInlierPrerejective sac;
  sac.setInputSource(keypoints);
  sac.setSourceFeatures(features);
  sac.setInputTarget(tmpl.keypoints);
  sac.setTargetFeatures(tmpl.features, tree.get());
  sac.setNumberOfSamples(3);
  sac.setCorrespondenceRandomness(config.sac_correspondence_randomness);
  sac.setSimilarityThreshold(static_cast<float>(config.prerejective_similarity));
  sac.setMinSampleDistance(static_cast<float>(config.sac_min_sample_distance));
  sac.setMaximumIterations(config.prerejective_iterations);
  sac.setMaxCorrespondenceDistance(distance);
  sac.setInlierFraction(static_cast<float>(config.prerejective_inlier_fraction));
  sac.setSeed(config.seed);
  sac.align(aligned);
  out.nearest_features = sac.nearestFeatures();
  out.converged = sac.hasConverged();
  if (out.converged) {
    out.object_T_camera = sac.getFinalTransformation();
    out.fitness = sac.getFitnessScore(distance);
  }
  return out;
}

// The inlier gate (registration.h): each segment keypoint with its nearest template feature (the
// consensus' match where it has one) and its inlier radius, widened by the depth noise at its
// depth; a pose's inliers are the correspondences it puts within their radius.
class InlierGate {
 public:
  InlierGate(const FeatureCloud& keypoints, const PfhrgbCloud& features, const ObjectTemplate& tmpl,
             const std::vector<pcl::Indices>& nearest_features, LazyFeatureTree& tree,
             const RegistrationConfig& config)
      : keypoints_(keypoints), template_keypoints_(*tmpl.keypoints) {
    radius_sq_.resize(keypoints.size());
    for (std::size_t i = 0; i < keypoints.size(); ++i) {
      const double r = WidenedByDepthNoise(config.inlier_distance, keypoints[i].z,
                                           config.inlier_depth_sigmas, config.depth_noise);
      radius_sq_[i] = static_cast<float>(r * r);
    }
    std::vector<int> nn_index(1);
    std::vector<float> nn_sq(1);
    for (std::size_t i = 0; i < keypoints.size(); ++i) {
      if (i < nearest_features.size() && !nearest_features[i].empty()) {
        matches_.emplace_back(i, static_cast<std::size_t>(nearest_features[i][0]));
        continue;
      }
      if (tree.get()->nearestKSearch(features[i], 1, nn_index, nn_sq) != 1) continue;
      matches_.emplace_back(i, static_cast<std::size_t>(nn_index[0]));
    }
  }
  int correspondences() const { return static_cast<int>(matches_.size()); }
  int inliers(const Eigen::Matrix4f& object_T_camera) const {
    const Eigen::Affine3f T(object_T_camera);
    int n = 0;
    for (const auto& [i, j] : matches_) {
      const Eigen::Vector3f p = T * keypoints_[i].getVector3fMap();
      n += (p - template_keypoints_[j].getVector3fMap()).squaredNorm() <= radius_sq_[i];
    }
    return n;
  }

 private:
  const FeatureCloud& keypoints_;
  const FeatureCloud& template_keypoints_;
  std::vector<float> radius_sq_;                              // per segment keypoint
  std::vector<std::pair<std::size_t, std::size_t>> matches_;  // segment, template keypoint
};

}  // namespace

RegistrationResult RegisterTemplate(const OrganizedCloud& segment, const ObjectTemplate& tmpl,
                                    const RegistrationConfig& config) {
  CheckInputs(tmpl, config);
  RegistrationResult result;

  // --- prepare: voxel, normals, PFHRGB of the segment.
  auto t0 = std::chrono::steady_clock::now();
  const FeatureCloud::Ptr source = PrepareSegmentCloud(segment, config);
  if (static_cast<int>(source->size()) < config.min_segment_points) {
    result.segment_points = static_cast<int>(source->size());
    result.status = RegistrationStatus::kTooFewPoints;
    result.times.prepare = MsSince(t0);
    return result;
  }
  FeatureCloud::Ptr source_keypoints =
      pose_detail::Keypoints(*source, config.features.keypoint_voxel);
  source_keypoints = Subsample(source_keypoints, config.max_segment_keypoints);
  PfhrgbCloud::Ptr source_features =
      pose_detail::ComputePfhrgb(source, source_keypoints, config.features);
  result.segment_points = static_cast<int>(source->size());
  result.segment_keypoints = static_cast<int>(source_keypoints->size());
  result.times.prepare = MsSince(t0);
  if (result.segment_points < config.min_segment_points ||
      result.segment_keypoints < config.min_inliers) {
    result.status = RegistrationStatus::kTooFewPoints;
    return result;
  }

  // --- consensus, and the upright hypotheses of large objects beside it.
  t0 = std::chrono::steady_clock::now();
  LazyFeatureTree feature_tree(tmpl, static_cast<float>(config.feature_search_epsilon));
  const std::vector<Eigen::Matrix4f> upright = UprightHypotheses(*source, tmpl, config);
  const ConsensusOutcome consensus =
      RunConsensus(source_keypoints, source_features, tmpl, config,
                   ConsensusDistance(*source_keypoints, config), feature_tree);
  if (consensus.converged) result.sac_fitness = consensus.fitness;
  result.times.consensus = MsSince(t0);
  if (!consensus.converged && upright.empty()) {
    // No sampled pose put enough segment keypoints on the template: nothing to refine.
    result.status = RegistrationStatus::kTooFewInliers;
    return result;
  }

  // --- gate: feature correspondences agreeing under the consensus' transform.
  t0 = std::chrono::steady_clock::now();
  const InlierGate gate(*source_keypoints, *source_features, tmpl, consensus.nearest_features,
                        feature_tree, config);
  result.correspondences = gate.correspondences();
  result.inliers = gate.inliers(consensus.object_T_camera);
  result.times.gate = MsSince(t0);
  result.camera_T_object = ToSE3(consensus.object_T_camera).inverse();
  result.sac_camera_T_object = result.camera_T_object;
  const bool sac_gate = consensus.converged && result.inliers >= config.min_inliers;
  if (!sac_gate && !config.gate_refined_pose) {
    result.status = RegistrationStatus::kTooFewInliers;
    return result;
  }

  // --- GICP refinement from the consensus' transform and its symmetry hypotheses, scoring, colour
  // gate, information matrix; the inlier gate again at the refined pose.
  RegistrationResult refined = result;
  std::vector<Eigen::Matrix4f> hypotheses;
  if (consensus.converged) {
    hypotheses = SymmetryHypotheses(*source, tmpl, consensus.object_T_camera, config);
  }
  hypotheses.insert(hypotheses.end(), upright.begin(), upright.end());
  RefineAndInform(source, tmpl, hypotheses, config, refined);
  if (refined.status == RegistrationStatus::kGicpFailed) {
    if (!sac_gate) refined.status = RegistrationStatus::kTooFewInliers;
    return refined;
  }
  t0 = std::chrono::steady_clock::now();
  refined.refined_inliers = gate.inliers(refined.camera_T_object.inverse().matrix().cast<float>());
  refined.times.gate += MsSince(t0);
  // Without gate_refined_pose the consensus' count alone decides (checked above).
  if (!config.gate_refined_pose ||
      PassesInlierGate(consensus.converged ? result.inliers : -1, refined.hypothesis,
                       refined.refined_inliers, config.min_inliers)) {
    return refined;
  }
  result.refined_inliers = refined.refined_inliers;
  result.hypotheses = refined.hypotheses;
  result.hypothesis = refined.hypothesis;
  result.score = refined.score;
  result.geometric_agreement = refined.geometric_agreement;
  result.colour_agreement = refined.colour_agreement;
  result.covered_agreement = refined.covered_agreement;
  result.fitness = refined.fitness;
  result.times = refined.times;
  result.status = RegistrationStatus::kTooFewInliers;
  return result;
}

}  // namespace moslam
