// The information matrix of a registration's final alignment: registration.h's "Information
// matrix" RULE (point-to-plane Fisher information, deflated for correlated points, plus a
// model-error floor that grows with the depth noise). Light code: a k-d tree search per point.
#pragma once

#include <Eigen/Core>

#include "moslam/pose_estimation/registration.h"

namespace moslam::pose_detail {

// The information (tangent order (w, v), for camera_T_object * Exp(xi)) of the pose
// object_T_camera^-1 that aligns `source` (segment points, camera frame) with `target` (template
// points with outward unit normals, object frame), by the RULE of registration.h. Symmetric
// positive definite.
Matrix6 AlignmentInformation(const FeatureCloud& source, const FeatureCloud::Ptr& target,
                             const Eigen::Matrix4f& object_T_camera,
                             const RegistrationConfig& config);

}  // namespace moslam::pose_detail
