// The one heavy translation unit of the front-end: PFHRGB, SAC-IA and GICP template
// instantiations (~40 s, ~1.4 GB to compile; shared/notes/frontend.md pitfall 4).
#include "moslam/pose_estimation/registration.h"

#include <pcl/features/normal_3d.h>
#include <pcl/features/pfhrgb.h>
#include <pcl/filters/voxel_grid.h>
#include <pcl/kdtree/kdtree_flann.h>
#include <pcl/registration/gicp.h>
#include <pcl/registration/ia_ransac.h>
#include <pcl/search/kdtree.h>

#include <Eigen/Dense>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <string>
#include <utility>
#include <vector>

#include "moslam/common/errors.h"
#include "moslam/render/rgbd.h"

namespace moslam {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kDegToRad = kPi / 180.0;

double MsSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

bool PositiveFinite(double x) { return std::isfinite(x) && x > 0.0; }

void Require(bool ok, const std::string& field, const std::string& what) {
  if (!ok) throw InvalidInputError(field + " " + what);
}

bool FiniteFeature(const pcl::PFHRGBSignature250& f) {
  for (float h : f.histogram) {
    if (!std::isfinite(h)) return false;
  }
  return true;
}

SE3 ToSE3(const Eigen::Matrix4f& T) {
  const Eigen::Matrix4d M = T.cast<double>();
  return SE3(SO3::FromMatrixNormalized(M.topLeftCorner<3, 3>()), M.topRightCorner<3, 1>());
}

}  // namespace

void FeatureConfig::validate() const {
  Require(PositiveFinite(voxel_size), "FeatureConfig.voxel_size", "must be positive");
  Require(PositiveFinite(normal_radius) && normal_radius > voxel_size,
          "FeatureConfig.normal_radius", "must be larger than voxel_size");
  Require(PositiveFinite(feature_radius) && feature_radius > voxel_size,
          "FeatureConfig.feature_radius", "must be larger than voxel_size");
  Require(std::isfinite(keypoint_voxel) && keypoint_voxel >= 0.0, "FeatureConfig.keypoint_voxel",
          "must be >= 0");
}

void RegistrationConfig::validate() const {
  features.validate();
  const std::string p = "RegistrationConfig.";
  Require(sac_iterations >= 1, p + "sac_iterations", "must be >= 1");
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
  Require(PositiveFinite(score_distance), p + "score_distance", "must be positive");
  Require(PositiveFinite(colour_tolerance), p + "colour_tolerance", "must be positive");
  Require(std::isfinite(chroma_dark_offset) && chroma_dark_offset >= 0.0,
          p + "chroma_dark_offset", "must be >= 0");
  Require(std::isfinite(min_geometric_agreement) && min_geometric_agreement >= 0.0 &&
              min_geometric_agreement <= 1.0,
          p + "min_geometric_agreement", "must be in [0, 1]");
  Require(std::isfinite(min_colour_agreement) && min_colour_agreement >= 0.0 &&
              min_colour_agreement <= 1.0,
          p + "min_colour_agreement", "must be in [0, 1]");
  Require(PositiveFinite(information_sigma_point), p + "information_sigma_point",
          "must be positive");
  Require(PositiveFinite(information_max_effective_points),
          p + "information_max_effective_points", "must be positive");
  Require(PositiveFinite(sigma_rotation_floor_deg), p + "sigma_rotation_floor_deg",
          "must be positive");
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

FeatureCloud::Ptr Keypoints(const FeatureCloud& surface, double keypoint_voxel) {
  if (keypoint_voxel <= 0.0) return std::make_shared<FeatureCloud>(surface);
  return VoxelDownsample(surface, keypoint_voxel);
}

PfhrgbCloud::Ptr ComputePfhrgb(const FeatureCloud::Ptr& surface, FeatureCloud::Ptr& keypoints,
                               double radius) {
  auto features = std::make_shared<PfhrgbCloud>();
  pcl::PFHRGBEstimation<FeaturePoint, FeaturePoint, pcl::PFHRGBSignature250> est;
  est.setInputCloud(keypoints);
  est.setSearchSurface(surface);
  est.setInputNormals(surface);
  est.setSearchMethod(std::make_shared<pcl::search::KdTree<FeaturePoint>>());
  est.setRadiusSearch(radius);
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

SE3 ObjectMeasurementInBody(const SE3& camera_T_object) {
  return BodyFromCamera() * camera_T_object;
}

namespace {

void CheckInputs(const ObjectTemplate& tmpl, const RegistrationConfig& config) {
  config.validate();
  if (!tmpl.cloud || !tmpl.keypoints || !tmpl.features || tmpl.cloud->empty() ||
      tmpl.keypoints->size() != tmpl.features->size()) {
    throw InvalidInputError("RegisterTemplate: template '" + tmpl.label +
                            "' is empty or its features do not match its keypoints");
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
  FeatureCloud raw;
  raw.reserve(segment.size());
  for (const auto& q : segment.points) {
    if (!std::isfinite(q.x) || !std::isfinite(q.y) || !std::isfinite(q.z)) continue;
    FeaturePoint p;
    p.x = q.x;
    p.y = q.y;
    p.z = q.z;
    p.rgba = q.rgba;
    p.normal_x = p.normal_y = p.normal_z = 0.0f;
    p.curvature = 0.0f;
    raw.push_back(p);
  }
  FeatureCloud::Ptr source = pose_detail::VoxelDownsample(raw, config.features.voxel_size);
  if (static_cast<int>(source->size()) < config.min_segment_points) return source;
  pose_detail::EstimateNormals(*source, config.features.normal_radius, Vector3::Zero());
  auto with_normals = std::make_shared<FeatureCloud>();
  for (const auto& p : source->points) {
    if (std::isfinite(p.normal_x) && std::isfinite(p.normal_y) && std::isfinite(p.normal_z)) {
      with_normals->push_back(p);
    }
  }
  return with_normals;
}

struct GicpOutcome {
  bool ok = false;
  Eigen::Matrix4f object_T_camera = Eigen::Matrix4f::Identity();
  double fitness = 0.0;
  FeatureCloud::Ptr target;  // the front-facing template points GICP aligned to
};

// The template points whose outward normal faces the camera at object_T_camera (back faces
// removed, so thin parts do not attract the segment to their hidden side); the whole template if
// fewer than min_segment_points face it.
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

GicpOutcome RunGicp(const FeatureCloud::Ptr& source, const ObjectTemplate& tmpl,
                    const Eigen::Matrix4f& object_T_camera_initial,
                    const RegistrationConfig& config) {
  GicpOutcome out;
  out.target = FrontFaces(tmpl, object_T_camera_initial, config);
  pcl::GeneralizedIterativeClosestPoint<FeaturePoint, FeaturePoint> gicp;
  gicp.setInputSource(source);
  gicp.setInputTarget(out.target);
  gicp.setMaximumIterations(config.gicp_max_iterations);
  gicp.setMaxCorrespondenceDistance(config.gicp_max_correspondence_distance);
  gicp.setTransformationEpsilon(config.gicp_transformation_epsilon);
  FeatureCloud refined;
  gicp.align(refined, object_T_camera_initial);
  out.object_T_camera = gicp.getFinalTransformation();
  out.ok = gicp.hasConverged() && out.object_T_camera.allFinite();
  if (out.ok) out.fitness = gicp.getFitnessScore(config.gicp_max_correspondence_distance);
  return out;
}

// Shading-invariant colour: (c + k) / (r + g + b + 3k), k = chroma_dark_offset (pulls dark,
// noisy colours towards grey).
Eigen::Vector3f Chroma(const FeaturePoint& p, float k) {
  const Eigen::Vector3f c(static_cast<float>(p.r) + k, static_cast<float>(p.g) + k,
                          static_cast<float>(p.b) + k);
  return c / c.sum();
}

struct PoseScore {
  double geometric = 0.0;  // fraction of segment points with a template point within reach
  double colour = 0.0;     // of those, the fraction whose colour agrees
  double score = 0.0;      // fraction of segment points agreeing in both
};

// The agreement rule of registration.h, segment points mapped by object_T_camera, against the
// template points facing the camera at that pose.
PoseScore ScorePose(const FeatureCloud& source, const ObjectTemplate& tmpl,
                    const Eigen::Matrix4f& object_T_camera, const RegistrationConfig& config) {
  const FeatureCloud::Ptr target = FrontFaces(tmpl, object_T_camera, config);
  pcl::KdTreeFLANN<FeaturePoint> tree;
  tree.setInputCloud(target);
  const auto k = static_cast<float>(config.chroma_dark_offset);
  const auto tol_sq = static_cast<float>(config.colour_tolerance * config.colour_tolerance);
  const Eigen::Affine3f T(object_T_camera);
  std::vector<int> idx;
  std::vector<float> sq;
  int geometric = 0, both = 0;
  for (const auto& sp : source.points) {
    FeaturePoint y;
    y.getVector3fMap() = T * sp.getVector3fMap();
    if (tree.radiusSearch(y, config.score_distance, idx, sq) <= 0) continue;
    ++geometric;
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
  return s;
}

// The symmetry hypotheses of registration.h: `initial` itself, then for each turn by
// 2 pi j / symmetry_turns (j = 1 .. turns - 1) about the object's z axis: through the object
// origin; through the vertical line of the segment's centroid (object frame); and the latter
// shifted horizontally so that the segment's centroid lands on the centroid of the template
// points facing the camera at that pose.
std::vector<Eigen::Matrix4f> Hypotheses(const FeatureCloud& source, const ObjectTemplate& tmpl,
                                        const Eigen::Matrix4f& initial,
                                        const RegistrationConfig& config) {
  std::vector<Eigen::Matrix4f> out{initial};
  Eigen::Vector3f centroid = Eigen::Vector3f::Zero();
  for (const auto& p : source.points) centroid += p.getVector3fMap();
  centroid /= static_cast<float>(std::max<std::size_t>(1, source.size()));
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
    const FeatureCloud::Ptr front = FrontFaces(tmpl, recentred, config);
    Eigen::Vector3f front_centroid = Eigen::Vector3f::Zero();
    for (const auto& q : front->points) front_centroid += q.getVector3fMap();
    front_centroid /= static_cast<float>(std::max<std::size_t>(1, front->size()));
    recentred.topRightCorner<3, 1>() += (front_centroid - c).cwiseProduct(horizontal);
    out.push_back(recentred);
  }
  return out;
}

// The information matrix of the final alignment (rule in registration.h).
Matrix6 Information(const FeatureCloud& source, const FeatureCloud::Ptr& target,
                    const Eigen::Matrix4f& object_T_camera, const RegistrationConfig& config) {
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
  const double sr = config.sigma_rotation_floor_deg * kDegToRad;
  const double st = config.sigma_translation_floor;
  Sigma.diagonal().head<3>().array() += sr * sr;
  Sigma.diagonal().tail<3>().array() += st * st;
  Sigma = 0.5 * (Sigma + Sigma.transpose());
  Matrix6 info = Sigma.ldlt().solve(Matrix6::Identity());
  return 0.5 * (info + info.transpose());
}

// GICP from each hypothesis, the best-scoring result kept (ties: the earlier hypothesis), the
// colour gate, then the information matrix; sets status, pose, fitness, scores, information and
// their times.
void RefineAndInform(const FeatureCloud::Ptr& source, const ObjectTemplate& tmpl,
                     const std::vector<Eigen::Matrix4f>& hypotheses,
                     const RegistrationConfig& config, RegistrationResult& result) {
  auto t0 = std::chrono::steady_clock::now();
  GicpOutcome best;
  PoseScore best_score;
  int best_index = -1;
  for (std::size_t h = 0; h < hypotheses.size(); ++h) {
    GicpOutcome g = RunGicp(source, tmpl, hypotheses[h], config);
    if (!g.ok) continue;
    const PoseScore s = ScorePose(*source, tmpl, g.object_T_camera, config);
    if (best_index < 0 || s.score > best_score.score) {
      best = std::move(g);
      best_score = s;
      best_index = static_cast<int>(h);
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
  result.camera_T_object = ToSE3(best.object_T_camera).inverse();
  if (best_score.geometric < config.min_geometric_agreement) {
    result.status = RegistrationStatus::kShapeMismatch;
    return;
  }
  if (best_score.colour < config.min_colour_agreement) {
    result.status = RegistrationStatus::kColourMismatch;
    return;
  }
  t0 = std::chrono::steady_clock::now();
  result.information = Information(*source, best.target, best.object_T_camera, config);
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
  RefineAndInform(source, tmpl, Hypotheses(*source, tmpl, initial, config), config, result);
  return result;
}

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
  if (config.max_segment_keypoints > 0 &&
      source_keypoints->size() > static_cast<std::size_t>(config.max_segment_keypoints)) {
    const std::size_t n = source_keypoints->size();
    const auto cap = static_cast<std::size_t>(config.max_segment_keypoints);
    auto strided = std::make_shared<FeatureCloud>();
    for (std::size_t j = 0; j < cap; ++j) strided->push_back((*source_keypoints)[j * n / cap]);
    source_keypoints = strided;
  }
  PfhrgbCloud::Ptr source_features = pose_detail::ComputePfhrgb(
      source, source_keypoints, config.features.feature_radius);
  result.segment_points = static_cast<int>(source->size());
  result.segment_keypoints = static_cast<int>(source_keypoints->size());
  result.times.prepare = MsSince(t0);
  if (result.segment_points < config.min_segment_points ||
      result.segment_keypoints < config.min_inliers) {
    result.status = RegistrationStatus::kTooFewPoints;
    return result;
  }

  // --- SAC-IA: segment (camera frame) -> template (object frame), i.e. object_T_camera.
  t0 = std::chrono::steady_clock::now();
  pcl::SampleConsensusInitialAlignment<FeaturePoint, FeaturePoint, pcl::PFHRGBSignature250> sac;
  sac.setInputSource(source_keypoints);
  sac.setSourceFeatures(source_features);
  sac.setInputTarget(tmpl.keypoints);
  sac.setTargetFeatures(tmpl.features);
  sac.setNumberOfSamples(3);
  sac.setMinSampleDistance(static_cast<float>(config.sac_min_sample_distance));
  sac.setCorrespondenceRandomness(config.sac_correspondence_randomness);
  sac.setMaximumIterations(config.sac_iterations);
  sac.setMaxCorrespondenceDistance(config.sac_max_correspondence_distance);
  std::srand(config.seed);
  FeatureCloud aligned;
  sac.align(aligned);
  const Eigen::Matrix4f object_T_camera_sac = sac.getFinalTransformation();
  result.sac_fitness = sac.getFitnessScore(config.sac_max_correspondence_distance);
  result.times.sac_ia = MsSince(t0);

  // --- gate: feature correspondences agreeing under the SAC-IA transform.
  t0 = std::chrono::steady_clock::now();
  pcl::KdTreeFLANN<pcl::PFHRGBSignature250> feature_tree;
  feature_tree.setInputCloud(tmpl.features);
  const Eigen::Affine3f T_sac(object_T_camera_sac);
  const float inlier_sq = static_cast<float>(config.inlier_distance * config.inlier_distance);
  std::vector<int> nn_index(1);
  std::vector<float> nn_sq(1);
  std::vector<std::pair<std::size_t, std::size_t>> matches;  // segment keypoint, template keypoint
  for (std::size_t i = 0; i < source_keypoints->size(); ++i) {
    if (feature_tree.nearestKSearch((*source_features)[i], 1, nn_index, nn_sq) != 1) continue;
    matches.emplace_back(i, static_cast<std::size_t>(nn_index[0]));
  }
  result.correspondences = static_cast<int>(matches.size());
  auto count_inliers = [&](const Eigen::Matrix4f& object_T_camera) {
    const Eigen::Affine3f T(object_T_camera);
    int n = 0;
    for (const auto& [i, j] : matches) {
      const Eigen::Vector3f p = T * (*source_keypoints)[i].getVector3fMap();
      n += (p - (*tmpl.keypoints)[j].getVector3fMap()).squaredNorm() <= inlier_sq;
    }
    return n;
  };
  result.inliers = count_inliers(object_T_camera_sac);
  result.times.gate = MsSince(t0);
  result.camera_T_object = ToSE3(object_T_camera_sac).inverse();
  result.sac_camera_T_object = result.camera_T_object;
  const bool sac_gate = result.inliers >= config.min_inliers;
  if (!sac_gate && !config.gate_refined_pose) {
    result.status = RegistrationStatus::kTooFewInliers;
    return result;
  }

  // --- GICP refinement from the SAC-IA transform and its symmetry hypotheses, scoring, colour
  // gate, information matrix; the inlier gate again at the refined pose.
  RegistrationResult refined = result;
  RefineAndInform(source, tmpl, Hypotheses(*source, tmpl, object_T_camera_sac, config), config,
                  refined);
  if (refined.status == RegistrationStatus::kGicpFailed) {
    if (!sac_gate) refined.status = RegistrationStatus::kTooFewInliers;
    return refined;
  }
  t0 = std::chrono::steady_clock::now();
  refined.refined_inliers =
      count_inliers(refined.camera_T_object.inverse().matrix().cast<float>());
  refined.times.gate += MsSince(t0);
  if (sac_gate || refined.refined_inliers >= config.min_inliers) return refined;
  result.refined_inliers = refined.refined_inliers;
  result.hypotheses = refined.hypotheses;
  result.hypothesis = refined.hypothesis;
  result.score = refined.score;
  result.geometric_agreement = refined.geometric_agreement;
  result.colour_agreement = refined.colour_agreement;
  result.fitness = refined.fitness;
  result.times = refined.times;
  result.status = RegistrationStatus::kTooFewInliers;
  return result;
}

}  // namespace moslam
