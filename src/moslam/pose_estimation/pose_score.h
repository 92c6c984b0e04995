// How well a pose of the template explains a segment: registration.h's AGREEMENT RULE (the score
// that ranks the hypotheses) and SHAPE RULE (the shape gate), and the depth-noise widening of its
// radii. Light code: k-d tree searches only, no PCL registration instantiations.
#pragma once

#include <Eigen/Core>

#include "moslam/pose_estimation/registration.h"

namespace moslam::pose_detail {

// A distance threshold at no depth noise, widened by `sigmas` of the sensor's depth noise at
// depth z: sqrt(d0^2 + (sigmas sigma(z))^2) (the agreement, inlier and consensus radii).
double WidenedByDepthNoise(double d0, double z, double sigmas, const AxialDepthNoise& noise);

// Shading-invariant colour: (c + k) / (r + g + b + 3k), k = chroma_dark_offset (pulls dark,
// noisy colours towards grey). Sums to 1.
Eigen::Vector3f Chroma(const FeaturePoint& p, float k);

struct PoseScore {
  double geometric = 0.0;  // fraction of segment points with a template point within reach
  double colour = 0.0;     // of those, the fraction whose colour agrees
  double score = 0.0;      // fraction of segment points agreeing in both
  double covered = 0.0;    // geometric points / covered points (with_covered only, else 0)
};

// The AGREEMENT RULE of registration.h: the segment points (`source`, camera frame) mapped by
// object_T_camera, against the template points facing the camera at that pose (FrontFaces). With
// `with_covered`, also the fraction of the segment points the template covers (a template point
// within score_distance of their pixel's ray) that agree in shape: clutter beside the object is
// then not evidence against the pose.
PoseScore ScorePose(const FeatureCloud& source, const ObjectTemplate& tmpl,
                    const Eigen::Matrix4f& object_T_camera, const RegistrationConfig& config,
                    bool with_covered = false);

// The SHAPE RULE of registration.h.
bool ShapeAgrees(const PoseScore& s, const RegistrationConfig& config);

}  // namespace moslam::pose_detail
