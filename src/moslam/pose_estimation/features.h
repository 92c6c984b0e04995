// Shared point-cloud preprocessing and PFHRGB features of segments and templates. The PFHRGB,
// SAC-IA and GICP template instantiations all live in registration.cc (one heavy translation
// unit, shared/notes/frontend.md pitfall 4); this header only declares.
#pragma once

#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include "moslam/geometry/se3.h"
#include "moslam/pose_estimation/organized_cloud.h"

namespace moslam {

using FeaturePoint = pcl::PointXYZRGBNormal;  // xyz (m), rgb, unit normal
using FeatureCloud = pcl::PointCloud<FeaturePoint>;
using PfhrgbCloud = pcl::PointCloud<pcl::PFHRGBSignature250>;

// The preprocessing and descriptor parameters. A template and the segments matched to it must
// use the same values (Register checks).
struct FeatureConfig {
  // 2 cm / 4 cm against 1.5 / 3 cm: PFHRGB 3x faster (fewer neighbours, cost ~ neighbours^2), 14
  // of 16 rendered chair views accepted against 13, median error 2 mm (measure_pose_estimation).
  double voxel_size = 0.02;      // m, pcl::VoxelGrid leaf
  double normal_radius = 0.04;   // m, segment normals (pcl::NormalEstimation)
  // m, PFHRGB neighbourhood. Its cost grows with the neighbours squared, so the neighbourhood
  // is taken on a coarser copy of the cloud (feature_surface_voxel): 7 cm over 3 cm voxels has
  // about the neighbours of 5 cm over 2 cm and twice the context. On rendered sequences (seed 7,
  // chairs25 and house, 2 robots, 40 poses, one frame in 2; 239 detections): the right template
  // feature nearest to a segment keypoint about twice as often on chairs and armchairs, accepted
  // 75 -> 86, 6 -> 5 of them more than 10 cm or 10 deg off (5 cm over 2 cm -> 7 over 3); 8 over 3:
  // 90 accepted, 5 off, but registration's 90th percentile 218 -> 277 ms (7 over 3: 224).
  double feature_radius = 0.07;
  // m, leaf of the PFHRGB search surface: the voxel_size cloud voxelled again (voxels whose normals
  // cancel, both sides of a thin part, dropped); <= voxel_size: the voxel_size cloud itself.
  double feature_surface_voxel = 0.03;
  // PFHRGB is computed at keypoints, the centroids of a coarser voxel grid of this leaf, over the
  // search surface above; SAC-IA and the inlier gate run on the keypoints, GICP on the voxel_size
  // cloud. 0 = a keypoint at every voxel_size point.
  double keypoint_voxel = 0.03;  // m

  // Throws InvalidInputError naming the first bad field.
  void validate() const;
  bool operator==(const FeatureConfig& o) const {
    return voxel_size == o.voxel_size && normal_radius == o.normal_radius &&
           feature_radius == o.feature_radius &&
           feature_surface_voxel == o.feature_surface_voxel && keypoint_voxel == o.keypoint_voxel;
  }
};

namespace pose_detail {

// pcl::VoxelGrid (centroid of xyz, rgb and normal; normals renormalised). With
// `drop_degenerate_normals`, voxels whose input normals cancel (mean normal shorter than 0.1:
// both sides of a thin part, internal faces) are dropped.
FeatureCloud::Ptr VoxelDownsample(const FeatureCloud& cloud, double leaf,
                                  bool drop_degenerate_normals = false);

// pcl::NormalEstimation within `radius`, normals flipped towards `viewpoint`.
void EstimateNormals(FeatureCloud& cloud, double radius, const Vector3& viewpoint);

// A segment's surface as registration prepares it: the finite points of `segment` (camera
// frame) voxelled at config.voxel_size; with at least `min_points` of them, normals within
// config.normal_radius flipped towards the camera (the origin), points without a normal dropped
// (fewer than `min_points`: returned voxelled, without normals). Segments and the rendered views
// of a view template (perception/view_template.h) go through the same steps, so that their
// features describe the same kind of surface.
FeatureCloud::Ptr PrepareSurface(const OrganizedCloud& segment, const FeatureConfig& config,
                                 std::size_t min_points);

// The keypoints of `surface` (a copy of it if keypoint_voxel == 0).
FeatureCloud::Ptr Keypoints(const FeatureCloud& surface, double keypoint_voxel);

// pcl::PFHRGBEstimation at `keypoints` within config.feature_radius over `surface` (which
// carries the normals) voxelled at config.feature_surface_voxel (when coarser than voxel_size);
// then removes the keypoints (and their features) whose descriptor is not finite, so
// keypoints[i] <-> features[i] stays aligned.
PfhrgbCloud::Ptr ComputePfhrgb(const FeatureCloud::Ptr& surface, FeatureCloud::Ptr& keypoints,
                               const FeatureConfig& config);

}  // namespace pose_detail
}  // namespace moslam
