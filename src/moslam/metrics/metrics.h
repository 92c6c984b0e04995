// Accuracy metrics of an estimate (paper eq. 1 and 2, shared/CONVENTIONS.md "Metrics").
//
// Over a set of variables i with estimate x_i = (R_i, t_i) and reference x*_i = (R*_i, t*_i):
//   ATE = sqrt( mean_i ||t_i - t*_i||^2 )                 in metres (RMS, as evo_ape's RMSE),
//   ARE = sqrt( mean_i ||Log(R*_i^T R_i)||^2 ) * 180/pi   in degrees (evo_ape -r angle_deg).
// Poses and object landmarks are reported separately. Every statistic runs over the keys of the
// *reference*: each must be in the estimate (InvalidInputError naming the first missing key
// otherwise); keys only the estimate has (e.g. variables the reference never saw) are ignored and
// not counted. An empty selection gives count = 0 and zero errors.
//
// CompareEstimates applies no alignment (the estimates share the gauge of CONVENTIONS.md, e.g. a
// distributed vs. the centralized Gauss-Newton estimate). CompareToGroundTruth first aligns the
// estimate to the ground truth with the rigid (no scale) Umeyama/Horn transform fitted to the pose
// positions only, as `evo_ape --align` does, and applies it to every estimated pose and object.
#pragma once

#include <functional>
#include <vector>

#include "moslam/geometry/se3.h"
#include "moslam/graph/pose_graph.h"

namespace moslam {

struct ErrorStats {
  double ate = 0.0;      // metres: RMS of the translation differences
  double are_deg = 0.0;  // degrees: RMS of the rotation angles of R_ref^T R
  int count = 0;         // number of variables compared
};

struct TrajectoryErrors {
  ErrorStats poses;
  ErrorStats objects;
};

// ATE/ARE over the keys of `reference` that `select` accepts (e.g. one robot's poses).
// Throws InvalidInputError when a selected key is missing from `estimate`, or when a compared pose
// is not finite.
ErrorStats ComputeErrorStats(const Values& estimate, const Values& reference,
                             const std::function<bool(const Key&)>& select);

// Poses and objects of `reference` against `estimate`, without alignment.
TrajectoryErrors CompareEstimates(const Values& estimate, const Values& reference);

// The rigid transform T (rotation and translation, no scale) minimising
// sum_i ||T * source_i - target_i||^2 (Umeyama 1991 without scale; Horn/Kabsch), a proper
// rotation (det +1) even when the best orthogonal fit is a reflection.
// Throws InvalidInputError when the sizes differ or a point is not finite, and
// UnderdeterminedError when the rotation is not unique: fewer than 3 points, or points that are
// all (numerically) collinear or coincident — evo_ape refuses the same "degenerate covariance".
SE3 AlignRigid(const std::vector<Vector3>& source, const std::vector<Vector3>& target);

// x -> T * x for every variable.
Values TransformValues(const SE3& T, const Values& values);

// The largest difference between two estimates of the same variables, over the keys of
// `reference`: max over keys of ||t_e - t_r|| (m) and ||R_e - R_r||_F; +infinity when `estimate`
// lacks one of those keys. For checking that two solvers reached the same estimate.
double MaxPoseDifference(const Values& estimate, const Values& reference);

struct GroundTruthErrors {
  TrajectoryErrors aligned;    // after the rigid alignment (what evo_ape --align reports)
  TrajectoryErrors unaligned;  // same as CompareEstimates(estimate, ground_truth)
  SE3 alignment;               // T with T * x_estimate ~ x_ground_truth
};

// Errors of `estimate` against `ground_truth` before and after aligning the estimate's pose
// positions to the ground truth's (over the pose keys of `ground_truth`; objects do not drive the
// alignment but are moved by it). Throws as CompareEstimates and AlignRigid (so the ground truth
// needs at least 3 non-collinear pose positions).
GroundTruthErrors CompareToGroundTruth(const Values& estimate, const Values& ground_truth);

}  // namespace moslam
