// Organized RGB-D frames and the pinhole camera that makes them: the type every perception
// stage (render -> detection -> segmentation -> registration) passes along.
//
// Frames:
//   camera (optical) frame: z forward (along the optical axis), x right, y down (OpenCV, ROS
//   REP 103 "_optical"). Pixel (u, v), u the column, v the row, images row-major from the top.
//   A point p = (x, y, z) in the camera frame projects to u = fx x / z + cx, v = fy y / z + cy;
//   pixel centres are at integer (u, v).
//   body frame of a robot: x forward, y left, z up (sim/robots.h). The camera sits at the body
//   origin looking along body x: body_T_camera = BodyFromCamera() (rotation only), so
//   body = R_bc * camera with camera z -> body x, camera x -> body -y, camera y -> body -z.
//
// Images (OpenCV types):
//   rgb    CV_8UC3, BGR channel order (cv::imread / cv::imwrite convention)
//   depth  CV_32FC1, metres along the optical axis (z, not ray length); 0 = no return
// TUM RGB-D files store depth as 16-bit PNG in units of 1/5000 m (render/tum_sequence.h).
#pragma once

#include <opencv2/core.hpp>

#include <string>

#include "moslam/geometry/se3.h"

namespace moslam {

struct PinholeIntrinsics {
  int width = 320;
  int height = 240;
  double fx = 160.0, fy = 160.0;  // pixels
  double cx = 159.5, cy = 119.5;  // pixels (the image centre for the defaults)

  // Square pixels, principal point at the image centre, given horizontal field of view.
  static PinholeIntrinsics FromHorizontalFov(int width, int height, double horizontal_fov_deg);
  // Throws InvalidInputError naming the first bad field (non-positive size or focal length,
  // non-finite values).
  void validate() const;
};

// Axial depth noise of an RGB-D sensor: sigma(z) = a + b (z - z0)^2 (m) at depth z (m). The
// defaults are a Kinect's, measured by Nguyen, Izadi and Lovell (3DIMPVT 2012); the renderer
// draws its noise from this model, and the registration's agreement radius widens with it.
struct AxialDepthNoise {
  double a = 0.0012;  // m
  double b = 0.0019;  // 1/m
  double z0 = 0.4;    // m
  double sigma(double z) const { return a + b * (z - z0) * (z - z0); }
  // Throws InvalidInputError naming the first bad field (`prefix` + field).
  void validate(const std::string& prefix = "AxialDepthNoise::") const;
};

struct RgbdFrame {
  cv::Mat rgb;    // CV_8UC3, BGR, height x width
  cv::Mat depth;  // CV_32FC1, metres (z), 0 = no return
  PinholeIntrinsics intrinsics;
  double timestamp = 0.0;  // s
};

// body_T_camera for a camera at the body origin looking along body x (see above).
SE3 BodyFromCamera();

}  // namespace moslam
