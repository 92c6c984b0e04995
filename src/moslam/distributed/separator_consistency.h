// Pairwise consistency of inter-robot loop closures (PCM: Mangelson, Dominic, Eustice and
// Vasudevan, ICRA 2018), the check that runs before the robust solve (robust_dgs.h) on g2o data.
//
// For two robots a < b, every separator i between them (a factor joining pose p_i of robot a and
// q_i of robot b, measurement z_i from p_i to q_i), with each robot's own estimate of its poses
// (its local graph solved alone: the factors between its own poses, anchored at its first pose),
// gives the transform between the two robots' frames:
//     T_i = A(p_i) z_i B(q_i)^-1.
// Two separators are consistent when T_i and T_j agree: e = Log(T_i^-1 T_j) (tangent order of
// CONVENTIONS.md) with e^T (Omega_i^-1 + Omega_j^-1)^-1 e <= threshold. The largest pairwise
// consistent set (a maximum clique, robust/max_clique.h) is kept; the others are rejected, and so
// is the whole set when it has fewer than min_support separators (one separator alone, or two
// agreeing by chance, confirm nothing). Drift of the local estimates between far-apart poses
// counts against inliers: the threshold must cover it (PCM uses the local covariances; here a
// scalar threshold in the factors' own units). Distributed: robot b sends robot a the local
// estimates of its separator poses (one DGS message, messages.h, counted); robot a decides.
#pragma once

#include <cstdint>
#include <vector>

#include "moslam/graph/pose_graph.h"

namespace moslam {

struct SeparatorConsistencyOptions {
  double threshold = 44.9;  // chi-square 6 dof at 0.999 (22.46) for the sum of two factors' errors
  int min_support = 3;      // separators of a robot pair confirming one another
  // Throws InvalidInputError naming the bad field.
  void validate() const;
};

struct SeparatorConsistencyResult {
  std::vector<bool> kept;  // per factor of the graph (true for every non-separator)
  int separators = 0;
  int rejected = 0;
  int robot_pairs = 0;
  int robot_pairs_rejected = 0;  // pairs whose best set was below min_support
  std::int64_t bytes = 0;        // the local estimates sent
  std::int64_t messages = 0;
};

// Throws InvalidInputError (bad options) and what the local solves throw.
SeparatorConsistencyResult CheckSeparatorConsistency(const PoseGraph& graph,
                                                     const SeparatorConsistencyOptions& options);

}  // namespace moslam
