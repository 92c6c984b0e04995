// Test-only synthetic data for pose_estimation tests: an asymmetric, position-coloured,
// chair-like object sampled on its surface, partial views of it, and an analytic RGB-D frame
// (floor + box). Header-only; not part of the library.
#pragma once

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "moslam/pose_estimation/organized_cloud.h"
#include "moslam/render/point_set.h"

namespace moslam::test {

struct Box3 {
  Vector3 lo, hi;
};

// Samples the 6 faces of an axis-aligned box on a grid of `spacing`, outward normals, colour from
// position (so that the object is not symmetric in colour).
inline void SampleBox(const Box3& b, double spacing, ColoredPointSet& out) {
  for (int axis = 0; axis < 3; ++axis) {
    for (int side = 0; side < 2; ++side) {
      const int a1 = (axis + 1) % 3, a2 = (axis + 2) % 3;
      const int n1 = std::max(1, static_cast<int>(std::ceil((b.hi[a1] - b.lo[a1]) / spacing)));
      const int n2 = std::max(1, static_cast<int>(std::ceil((b.hi[a2] - b.lo[a2]) / spacing)));
      for (int i = 0; i <= n1; ++i) {
        for (int j = 0; j <= n2; ++j) {
          Vector3 p;
          p[axis] = side == 0 ? b.lo[axis] : b.hi[axis];
          p[a1] = b.lo[a1] + (b.hi[a1] - b.lo[a1]) * i / n1;
          p[a2] = b.lo[a2] + (b.hi[a2] - b.lo[a2]) * j / n2;
          Vector3 n = Vector3::Zero();
          n[axis] = side == 0 ? -1.0 : 1.0;
          out.points.push_back(p);
          out.normals.push_back(n);
          auto c = [](double x) {
            return static_cast<unsigned char>(std::clamp(x, 0.0, 1.0) * 255.0);
          };
          // BGR: blue by height, green by lateral position, red by depth, stripes on x.
          const double stripe = std::fmod(std::abs(p.x() + p.y() + 2.0 * p.z()), 0.2) < 0.1 ? 0.3 : 0.0;
          out.colours_bgr.emplace_back(c(0.5 + p.z()), c(0.5 + 1.5 * p.y()),
                                       c(0.3 + p.x() + stripe));
        }
      }
    }
  }
}

// A chair-sized (0.5 x 0.5 x 0.9 m), asymmetric object: seat, back (at -x), two legs of
// different thickness and an arm rest on +y only. Object frame: centre, x forward, z up.
inline ColoredPointSet MakeTestObject(double spacing = 0.01) {
  ColoredPointSet s;
  SampleBox({Vector3(-0.25, -0.25, -0.05), Vector3(0.25, 0.25, 0.0)}, spacing, s);    // seat
  SampleBox({Vector3(-0.25, -0.25, 0.0), Vector3(-0.20, 0.25, 0.45)}, spacing, s);    // back
  SampleBox({Vector3(-0.25, -0.25, -0.45), Vector3(0.25, -0.20, -0.05)}, spacing, s); // side panel
  SampleBox({Vector3(0.15, 0.15, -0.45), Vector3(0.25, 0.25, -0.05)}, spacing, s);    // thick leg
  SampleBox({Vector3(-0.20, 0.20, 0.10), Vector3(0.20, 0.25, 0.15)}, spacing, s);     // arm rest
  return s;
}

// The points of `object` a camera at the origin sees (normal facing the camera; no occlusion
// test) after placing the object at camera_T_object, with isotropic Gaussian noise.
inline OrganizedCloud::Ptr ViewOf(const ColoredPointSet& object, const SE3& camera_T_object,
                                  double noise_sigma, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, noise_sigma);
  auto cloud = std::make_shared<OrganizedCloud>();
  for (std::size_t i = 0; i < object.size(); ++i) {
    const Vector3 p = camera_T_object.transformFrom(object.points[i]);
    const Vector3 n = camera_T_object.rotation() * object.normals[i];
    if (n.dot(-p) <= 0.0) continue;
    OrganizedPoint q;
    q.x = static_cast<float>(p.x() + noise(rng));
    q.y = static_cast<float>(p.y() + noise(rng));
    q.z = static_cast<float>(p.z() + noise(rng));
    q.b = object.colours_bgr[i][0];
    q.g = object.colours_bgr[i][1];
    q.r = object.colours_bgr[i][2];
    q.a = 255;
    cloud->push_back(q);
  }
  return cloud;
}

// Ray/axis-aligned-box intersection (slabs); returns the entry distance or -1.
inline double RayBox(const Vector3& dir, const Box3& b) {
  double t0 = 0.0, t1 = 1e9;
  for (int a = 0; a < 3; ++a) {
    if (std::abs(dir[a]) < 1e-12) {
      if (0.0 < b.lo[a] || 0.0 > b.hi[a]) return -1.0;
      continue;
    }
    double ta = b.lo[a] / dir[a], tb = b.hi[a] / dir[a];
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta);
    t1 = std::min(t1, tb);
  }
  return t0 <= t1 && t0 > 0.0 ? t0 : -1.0;
}

// A camera-axis-aligned box and its colour (BGR).
struct ColouredBox3 {
  Box3 box;
  cv::Vec3b bgr;
};

// An analytic frame: level camera at height `camera_height` above an infinite grey floor
// (camera y = +camera_height), and camera-axis-aligned boxes (camera frame). A wall facing the
// camera at depth wall_z is added if wall_z > 0.
inline RgbdFrame FloorAndBoxesFrame(const PinholeIntrinsics& K, double camera_height,
                                    const std::vector<ColouredBox3>& boxes, double wall_z = 0.0) {
  RgbdFrame f;
  f.intrinsics = K;
  f.rgb = cv::Mat(K.height, K.width, CV_8UC3, cv::Scalar(0, 0, 0));
  f.depth = cv::Mat(K.height, K.width, CV_32FC1, cv::Scalar(0.0f));
  for (int v = 0; v < K.height; ++v) {
    for (int u = 0; u < K.width; ++u) {
      const Vector3 dir((u - K.cx) / K.fx, (v - K.cy) / K.fy, 1.0);  // z = 1
      double best = 1e9;
      cv::Vec3b colour;
      if (dir.y() > 1e-9) {
        const double t = camera_height / dir.y();
        if (t < 8.0) {
          best = t;
          colour = cv::Vec3b(120, 120, 120);
        }
      }
      if (wall_z > 0.0 && wall_z < best) {
        best = wall_z;
        colour = cv::Vec3b(200, 200, 200);
      }
      for (const ColouredBox3& b : boxes) {
        const double tb = RayBox(dir, b.box);
        if (tb > 0.0 && tb < best) {
          best = tb;
          colour = b.bgr;
        }
      }
      if (best < 1e9) {
        f.depth.at<float>(v, u) = static_cast<float>(best);  // dir.z = 1: t is the depth
        f.rgb.at<cv::Vec3b>(v, u) = colour;
      }
    }
  }
  return f;
}

// One red box (rgb 200, 30, 30).
inline RgbdFrame FloorAndBoxFrame(const PinholeIntrinsics& K, double camera_height,
                                  const Box3& object, double wall_z = 0.0) {
  return FloorAndBoxesFrame(K, camera_height, {{object, cv::Vec3b(30, 30, 200)}}, wall_z);
}

}  // namespace moslam::test
