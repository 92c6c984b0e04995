#include "moslam/pose_estimation/organized_cloud.h"

#include <cmath>
#include <limits>
#include <string>

#include "moslam/common/errors.h"

namespace moslam {

OrganizedCloud::Ptr MakeOrganizedCloud(const RgbdFrame& frame) {
  const PinholeIntrinsics& K = frame.intrinsics;
  K.validate();
  if (frame.rgb.type() != CV_8UC3) {
    throw InvalidInputError("MakeOrganizedCloud: frame.rgb must be CV_8UC3 (BGR)");
  }
  if (frame.depth.type() != CV_32FC1) {
    throw InvalidInputError("MakeOrganizedCloud: frame.depth must be CV_32FC1 (metres)");
  }
  if (frame.rgb.cols != K.width || frame.rgb.rows != K.height || frame.depth.cols != K.width ||
      frame.depth.rows != K.height) {
    throw InvalidInputError("MakeOrganizedCloud: frame.rgb and frame.depth must be " +
                            std::to_string(K.width) + "x" + std::to_string(K.height) +
                            " (the intrinsics' size)");
  }
  auto cloud = std::make_shared<OrganizedCloud>(static_cast<std::uint32_t>(K.width),
                                                static_cast<std::uint32_t>(K.height));
  cloud->is_dense = false;
  cloud->sensor_origin_.setZero();
  cloud->sensor_orientation_.setIdentity();
  const float nan = std::numeric_limits<float>::quiet_NaN();
  for (int v = 0; v < K.height; ++v) {
    const float* d = frame.depth.ptr<float>(v);
    const cv::Vec3b* c = frame.rgb.ptr<cv::Vec3b>(v);
    for (int u = 0; u < K.width; ++u) {
      OrganizedPoint& p = cloud->at(u, v);
      p.b = c[u][0];
      p.g = c[u][1];
      p.r = c[u][2];
      p.a = 255;
      const float z = d[u];
      if (!std::isfinite(z) || z <= 0.0f) {
        p.x = p.y = p.z = nan;
        continue;
      }
      const Vector3 q = BackProject(K, u, v, z);
      p.x = static_cast<float>(q.x());
      p.y = static_cast<float>(q.y());
      p.z = z;
    }
  }
  return cloud;
}

Vector3 BackProject(const PinholeIntrinsics& K, double u, double v, double z) {
  return Vector3((u - K.cx) * z / K.fx, (v - K.cy) * z / K.fy, z);
}

std::optional<Eigen::Vector2d> Project(const PinholeIntrinsics& K, const Vector3& p_camera) {
  if (!(p_camera.z() > 0.0)) return std::nullopt;
  return Eigen::Vector2d(K.fx * p_camera.x() / p_camera.z() + K.cx,
                         K.fy * p_camera.y() / p_camera.z() + K.cy);
}

}  // namespace moslam
