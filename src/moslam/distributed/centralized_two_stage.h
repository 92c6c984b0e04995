// The two-stage relaxation of DGS (shared/DGS.md) solved centrally: one linear system per stage
// over all variables, the fixed point the distributed sweeps converge to.
//
//   stage 1: min sum ||R_b - R_a R_ab||_F^2 over unconstrained 3x3 matrices (chordal), then
//            R = U diag(1, 1, det(U V^T)) V^T;
//   stage 2: one Gauss-Newton step on the 12-D residual [vec(R_a R_ab - R_b); t_b - t_a - R_a t_ab]
//            linearised at (R_hat, t = 0): R = R_hat Exp(dtheta), t = dt.
//
// The terms are those the robot agents use (two_stage_terms.h). The anchor (GaugeAnchor: first
// pose of robot 0) is eliminated and held at its initial value in both stages, exactly as the
// agent that owns it does; variables missing from `initial` start at the identity.
#pragma once

#include <Eigen/Core>
#include <map>

#include "moslam/graph/pose_graph.h"

namespace moslam {

struct TwoStageOptions {
  bool weight_by_information = false;  // unit weights, as the DGS reference
};

struct TwoStageResult {
  std::map<Key, Eigen::VectorXd> relaxed_rotations;  // stage 1 before projection, row by row
  std::map<Key, Matrix3> rotations;                  // projected (the anchor: its initial value)
  Values values;                                     // after stage 2
};

// Throws UnderdeterminedError when robot 0 has no pose or part of the graph is not connected
// to the anchor, NumericalError when a system is singular.
TwoStageResult CentralizedTwoStage(const PoseGraph& graph, const Values& initial,
                                   const TwoStageOptions& options = {});

// Stage 2 alone, linearised at the given rotations (one per variable).
Values CentralizedPoseStep(const PoseGraph& graph, const std::map<Key, Matrix3>& rotations,
                           const Key& anchor, const SE3& anchor_pose,
                           const TwoStageOptions& options = {});

}  // namespace moslam
