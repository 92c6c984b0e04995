// A coloured, oriented point set: an object model sampled to points (render/object_models.h),
// the input of a registration template (pose_estimation/). Plain Eigen/OpenCV types, so that the
// rendering side does not depend on PCL.
#pragma once

#include <opencv2/core.hpp>
#include <vector>

#include "moslam/geometry/se3.h"

namespace moslam {

struct ColoredPointSet {
  std::vector<Vector3> points;          // m, in the object frame (sim/world.h: centre, x fwd, z up)
  std::vector<Vector3> normals;         // unit, outward; same size as points
  std::vector<cv::Vec3b> colours_bgr;   // same size as points
  std::size_t size() const { return points.size(); }
};

}  // namespace moslam
