// Initial estimates for a pose graph, all in the gauge of CONVENTIONS.md: the anchor (first pose
// of robot 0) is held at `anchor_pose` and everything else is solved relative to it.
#pragma once

#include <map>

#include "moslam/graph/pose_graph.h"

namespace moslam {

struct ChordalOptions {
  // Weight each edge's rotation term by trace(Omega_rot)/3 and its translation term by
  // Omega_trans (in the frame of the edge's first pose). Off: unit weights, as the DGS reference.
  bool weight_by_information = true;
};

// Stage 1 of the chordal relaxation: minimise sum ||R_b - R_a R_ab||_F^2 over unconstrained 3x3
// matrices with the anchor's rotation fixed, then project each to SO(3) (SVD). Priors enter as
// edges to a fixed rotation. Throws UnderdeterminedError when the graph is disconnected.
std::map<Key, SO3> ChordalRotations(const PoseGraph& graph, const SO3& anchor_rotation = SO3(),
                                    const ChordalOptions& options = {});

// Stage 2 (translations): with rotations fixed, minimise sum ||R_a^T (t_b - t_a) - t_ab||^2
// (linear least squares) with the anchor's translation fixed.
Values TranslationsGivenRotations(const PoseGraph& graph, const std::map<Key, SO3>& rotations,
                                  const Vector3& anchor_translation = Vector3::Zero(),
                                  const ChordalOptions& options = {});

// Both stages: the chordal-relaxation initial estimate.
Values ChordalInitialization(const PoseGraph& graph, const SE3& anchor_pose = SE3(),
                             const ChordalOptions& options = {});

// Composes measurements along a spanning tree grown from the anchor, taking odometry edges
// (same robot, consecutive pose indices) before any other edge: dead reckoning where the graph
// has chains, the shortest bridge elsewhere.
Values OdometryInitialization(const PoseGraph& graph, const SE3& anchor_pose = SE3());

}  // namespace moslam
