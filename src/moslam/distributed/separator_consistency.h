// Pairwise consistency of inter-robot loop closures (PCM: Mangelson, Dominic, Eustice and
// Vasudevan, ICRA 2018), the check that runs before the robust solve (robust_dgs.h) on g2o data.
//
// For two robots a < b, with each robot's own estimate of its variables (its local graph solved
// alone: the factors between its own variables, anchored at its first pose) and their marginal
// covariances there (solver/marginals.h), two separators i and j (factors joining a's variable
// A_i to b's B_i, measurement z_i from A_i to B_i) close a loop through both maps:
//     L_ij = z_i^-1 (A_i^-1 A_j) z_j (B_j^-1 B_i),
// the identity when both are right. They are consistent when
//     e^T Sigma_e^-1 e <= threshold,   e = Log(L_ij) (tangent order of CONVENTIONS.md),
// Sigma_e the first-order covariance of e from z_i, z_j (their information's inverse) and the
// joint covariances of (A_i, A_j) in a's map and of (B_i, B_j) in b's: the drift of each map
// between the two separators' variables is in the test, so two right separators far apart in a
// drifting map still agree, and e^T Sigma_e^-1 e is chi-square with 6 degrees of freedom when
// the informations are right (PCM's test, Mangelson et al. eq. 7, with marginal covariances).
// The largest pairwise consistent set (a maximum clique, robust/max_clique.h) is kept; the others
// are rejected. A pair whose best set has fewer than min_support separators does not confirm
// itself (one separator alone, or two agreeing by chance): it is rejected, unless its two robots
// are linked through confirmed pairs and its best set has linked_min_support separators: then
// that set is kept for the robust solve, where the loop through the team tests it as well.
// Rejecting every such pair threw away right separators of short rendezvous: on generated with
// known initial poses and no outliers, 2 runs of 10 at 4 robots and 2 at 6 moved the estimate
// 3 cm - 5 m from the least-squares one. Keeping lone separators too (linked_min_support 1) lets
// GNC decide more than it can: on blocks_world with 90 % wrong separators (16 robots) it then
// rejected right ones. Distributed: robot b sends robot
// a the local estimates of its separator variables (a DGS message) and their joint covariance (a
// covariance message, messages.h), both counted; robot a decides.
#pragma once

#include <cstdint>
#include <vector>

#include "moslam/graph/pose_graph.h"
#include "moslam/robust/gnc.h"

namespace moslam {

struct SeparatorConsistencyOptions {
  double threshold = 22.46;  // chi-square, 6 degrees of freedom, at 0.999
  int min_support = 3;      // separators of a robot pair confirming one another
  // A pair below min_support whose robots are linked through confirmed pairs: its best set is
  // kept for the robust solve when it has this many separators (min_support: never).
  int linked_min_support = 2;
  // false: the maps taken as exact (Sigma_e from z_i and z_j alone; no covariance message), for
  // graphs whose information does not describe their noise: blocks_world's is the identity while
  // its residuals are 100x smaller, and the marginals of such maps (1 rad per odometry step) make
  // every pair look consistent.
  bool map_uncertainty = true;
  // Throws InvalidInputError naming the bad field.
  void validate() const;
};

struct SeparatorConsistencyResult {
  std::vector<bool> kept;  // per factor of the graph (true for every non-separator)
  int separators = 0;
  int rejected = 0;
  int robot_pairs = 0;
  int robot_pairs_rejected = 0;  // pairs whose separators were all rejected
  int robot_pairs_deferred = 0;  // pairs below min_support kept for the robust solve
  int deferred = 0;              // their separators kept
  std::int64_t bytes = 0;        // the local estimates and covariances sent
  std::int64_t messages = 0;
};

// robust (empty, or one flag per factor of graph): the intra-robot factors it marks (object
// measurements) are robust in each robot's own map too: the map is then its GNC-TLS estimate
// (robust/gnc.h, with `local`) and its covariances those of the weighted graph, so that a wrong
// association inside one robot's map does not make every separator of that robot disagree.
// Throws InvalidInputError (bad options, a mask of the wrong size) and what the local solves throw.
SeparatorConsistencyResult CheckSeparatorConsistency(const PoseGraph& graph,
                                                     const SeparatorConsistencyOptions& options,
                                                     const std::vector<bool>& robust = {},
                                                     const GncOptions& local = {});

}  // namespace moslam
