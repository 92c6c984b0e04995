// Organized point clouds from RGB-D frames, and the pinhole projection both ways.
//
// Frames and units (render/rgbd.h): points are in the camera optical frame (z forward along the
// optical axis, x right, y down), in metres. Pixel (u, v) = (column, row), pixel centres at
// integer coordinates: a pixel with depth z back-projects to
//   p = ((u - cx) z / fx, (v - cy) z / fy, z).
// The organized cloud has the frame's width x height, row-major from the top row (point index
// v * width + u); pixels with no return (depth 0, negative or non-finite) are NaN points and the
// cloud is marked not dense. sensor_origin_ = 0 and sensor_orientation_ = identity: the cloud is in
// the camera frame.
#pragma once

#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <optional>

#include <Eigen/Core>

#include "moslam/geometry/se3.h"
#include "moslam/render/rgbd.h"

namespace moslam {

using OrganizedPoint = pcl::PointXYZRGBA;
using OrganizedCloud = pcl::PointCloud<OrganizedPoint>;

// Builds the organized cloud of `frame`. Throws InvalidInputError if the intrinsics are invalid,
// the images are not CV_8UC3 / CV_32FC1, or their sizes differ from the intrinsics.
OrganizedCloud::Ptr MakeOrganizedCloud(const RgbdFrame& frame);

// The camera-frame point seen at pixel (u, v) with depth z (metres along the optical axis).
Vector3 BackProject(const PinholeIntrinsics& K, double u, double v, double z);

// The pixel (u, v) where the camera-frame point p projects; nullopt if p is not in front of the
// camera (z <= 0). The pixel may lie outside the image.
std::optional<Eigen::Vector2d> Project(const PinholeIntrinsics& K, const Vector3& p_camera);

// The (u, v) pixel of point index `index` of an organized cloud of the given width.
inline Eigen::Vector2i PixelOfIndex(std::size_t index, std::size_t width) {
  return Eigen::Vector2i(static_cast<int>(index % width), static_cast<int>(index / width));
}

}  // namespace moslam
