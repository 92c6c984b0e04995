// Depth smoothing of a segment along its pixels' rays: less axial noise for far views.
//
// An RGB-D sensor's depth noise is axial (along the pixel's ray) and grows with the square of the
// depth (AxialDepthNoise: a Kinect's 4.1 cm at 5 m, 8.4 cm at 7 m), while the pixels' rays are
// exact. A far object's segment is then a cloud of points scattered along their rays by more than
// the features' and the gate's scales, and the registration rarely accepts it. Each point's depth
// is replaced by a local fit over its neighbours of the same segment, and the point moved along
// its own ray to the new depth (x/z and y/z unchanged), as depth-image filters do before fusion
// (KinectFusion's bilateral filter):
//   neighbours  : segment pixels within `radius` (m, lateral, at the pixel's depth) of it, at most
//                 `max_window` pixels away in each direction;
//   weights     : spatial Gaussian of sigma radius / 2 on the lateral distance, times a range
//                 Gaussian on the depth difference of sigma range_sigmas sqrt(2) sigma(z) (two
//                 noisy depths differ by sqrt(2) sigma; a step larger than that, a part in front
//                 of another, is not smoothed across);
//   fit         : inverse depth linear in the lateral offset, by weighted least squares (a plane
//                 has an inverse depth linear in its pixel coordinates, so planes stay unbiased,
//                 also at the segment's edge where the neighbours lie on one side); the weighted
//                 mean of the inverse depths with fewer than `min_neighbours` neighbours or a
//                 degenerate spread.
// Points whose noise sigma(z) is below `min_noise` are left as they are (near views: the voxel
// grid of the registration averages them already).
// On a plane 6 m away the depth error falls from 6.1 to 2.0 cm RMS (depth_smoothing_test.cc).
// Chosen on the seed-7 selection sequences (chairs25 and house, 2 robots, 40 poses, one frame in
// 2; `moslam perceive --world`, 225 detections): accepted 87 without smoothing, 115 with
// min_noise 1 cm, 120 with 2 cm (the default; more than 10 cm / 10 deg off: 5, 13, 12); radius
// 8 cm 105, range_sigmas 3 108. Views beyond 7 m stay poor (median 6.4 cm / 15 deg), which the
// registration's information floors say (RegistrationConfig::information_floor_noise).
// The lateral offsets come from the rays alone (x/z, y/z of the organized cloud's points), so no
// intrinsics are needed. Units: metres, camera optical frame (pose_estimation/organized_cloud.h).
#pragma once

#include <string>
#include <vector>

#include "moslam/pose_estimation/organized_cloud.h"
#include "moslam/render/rgbd.h"

namespace moslam {

struct DepthSmoothingConfig {
  bool enabled = true;
  double radius = 0.06;       // m, lateral
  double range_sigmas = 2.0;  // of sqrt(2) sigma(z)
  int max_window = 8;         // pixels each side
  int min_neighbours = 6;     // for the linear fit (itself included)
  double min_noise = 0.02;    // m: sigma(z) below this is left alone (z < 3.6 m for a Kinect)

  // Throws InvalidInputError naming the first bad field (`prefix` + field).
  void validate(const std::string& prefix = "DepthSmoothingConfig.") const;
};

// The points `indices` of the organized `cloud` (its segment), in that order, each moved along
// its ray to the smoothed depth; colours kept. Indices of non-finite points or outside the cloud
// throw InvalidInputError, as does an unorganized cloud. Disabled: the points as they are.
OrganizedCloud::Ptr SmoothAlongRays(const OrganizedCloud& cloud, const std::vector<int>& indices,
                                    const AxialDepthNoise& noise,
                                    const DepthSmoothingConfig& config);

}  // namespace moslam
