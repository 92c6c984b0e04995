// The candidate poses registration refines with GICP (registration.h: "Symmetry hypotheses" and
// "Upright hypotheses"), and the template points a camera sees at a pose. Light code: Eigen and
// point clouds, no PCL registration instantiations (those stay in registration.cc).
//
// Poses are object_T_camera (segment points, camera frame -> template, object frame) as 4 x 4
// float matrices, as PCL's registration takes them.
#pragma once

#include <Eigen/Core>
#include <vector>

#include "moslam/pose_estimation/registration.h"

namespace moslam::pose_detail {

// Mean of the points (zero for an empty cloud).
Eigen::Vector3f Centroid(const FeatureCloud& cloud);

// The template points whose outward normal faces the camera at object_T_camera (back faces
// removed, so thin parts do not attract the segment to their hidden side); the whole template if
// fewer than config.min_segment_points face it. tmpl.cloud must not be null.
FeatureCloud::Ptr FrontFaces(const ObjectTemplate& tmpl, const Eigen::Matrix4f& object_T_camera,
                             const RegistrationConfig& config);

// The symmetry hypotheses: `initial` itself, then for each turn by 2 pi j / symmetry_turns
// (j = 1 .. turns - 1) about the object's z axis: through the object origin; through the vertical
// line of the segment's centroid (object frame); and the latter shifted horizontally so that the
// segment's centroid lands on the centroid of the template points facing the camera at that pose.
// 1 + 3 (symmetry_turns - 1) poses.
std::vector<Eigen::Matrix4f> SymmetryHypotheses(const FeatureCloud& source,
                                                const ObjectTemplate& tmpl,
                                                const Eigen::Matrix4f& initial,
                                                const RegistrationConfig& config);

// The upright hypotheses: the object standing on a floor whose up direction in the camera frame
// is config.camera_up; yaw along the principal horizontal axis of the segment and its turns by
// 2 pi / upright_yaws; the template's camera-facing points centred on the segment's centroid.
// upright_yaws poses; none when the template's horizontal extent is below upright_min_extent,
// upright_yaws is 0 or the segment is empty.
std::vector<Eigen::Matrix4f> UprightHypotheses(const FeatureCloud& source,
                                               const ObjectTemplate& tmpl,
                                               const RegistrationConfig& config);

}  // namespace moslam::pose_detail
