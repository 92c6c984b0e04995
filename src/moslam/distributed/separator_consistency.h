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
// Two object-object separators that pair one landmark with two different landmarks exclude each
// other (one_to_one_objects, below). The largest pairwise consistent set (a maximum clique,
// robust/max_clique.h) is kept; the others are rejected. A pair whose largest set has fewer than
// min_support separators does not confirm itself (one separator alone, or two agreeing by chance):
// it is rejected, unless its two robots are linked through confirmed pairs and its largest set has
// linked_min_support separators: then every separator of a largest set (there may be several,
// tied) is kept for the robust solve, where the loop through the team tests them as well.
// Rejecting every such pair threw away right separators of short rendezvous: on generated with
// known initial poses and no outliers, 2 runs of 10 at 4 robots and 2 at 6 moved the estimate
// 3 cm - 5 m from the least-squares one. Keeping lone separators too (linked_min_support 1) lets
// GNC decide more than it can: on blocks_world with 90 % wrong separators (16 robots) it then
// rejected right ones. Distributed: robot b sends robot
// a the local estimates of its separator variables (a DGS message) and their joint covariance (a
// covariance message, messages.h), both counted; robot a decides.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <vector>

#include "moslam/distributed/messages.h"
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
  // Object separators are associations: a landmark of one robot is one object, the same as at most
  // one landmark of the other. Two object-object separators that join one landmark to two different
  // landmarks of the other robot exclude each other (never in one consistent set, as CLIPPER's one-
  // to-one constraint), whatever their loop says: a landmark of b wrongly paired with several
  // landmarks of a that a's map holds close together agreed with one another, and that set won over
  // the right one (generated, 6 robots, 70 % injected wrong pairs, seed 3: four wrong pairs on one
  // landmark tied with the four right ones and were kept). The cost: a robot that mapped one object
  // twice keeps one of its two right pairs to the other's landmark. Pose-pose separators (g2o loop
  // closures) are not associations and are not affected.
  bool one_to_one_objects = true;
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
  // Per factor of the graph: for a separator, how many of the separators kept of its robot pair
  // it passes the pairwise test with (one-to-one exclusions counting as failures); -1 for the
  // other factors and for pairs not checked. What RobustDgsOptions::retest_left_out reads.
  std::vector<int> support;
  // Per factor of the graph: whether it is in the runner-up set of its robot pair
  // (PairConsistency::runner_up) when the pair is kept (false for the other factors and pairs).
  // What RobustDgsOptions::retest_groups reads.
  std::vector<bool> runner_up;
};

// One robot's own map for the check: the factors between its own variables in `graph` (the whole
// graph or the robot's subgraph: the same factors in the same order) solved alone, its first pose
// at the identity (the gauge), and with `marginals` the covariances there. robust (empty, or one
// flag per factor of graph): the intra-robot factors it marks are robust (see below). Throws what
// the local solves throw.
class SeparatorCheckMap {
 public:
  SeparatorCheckMap(const PoseGraph& graph, int robot, const std::vector<bool>& robust,
                    const GncOptions& gnc, bool marginals);
  ~SeparatorCheckMap();
  SeparatorCheckMap(const SeparatorCheckMap&) = delete;
  SeparatorCheckMap& operator=(const SeparatorCheckMap&) = delete;

  int robot() const { return robot_; }
  // Whether every key is in the map (a variable its own factors reach).
  bool hasAll(const std::vector<Key>& keys) const;
  // The map's estimate of one of its variables (InvalidInputError if it lacks it).
  const SE3& pose(const Key& key) const;
  // What it sends the other robot of a pair: the local estimates of `keys` (its own, increasing;
  // a DGS message of stage kPose from robot()) and their joint covariance (6 per key; zero-size
  // without marginals). Throws InvalidInputError for a key not in the map.
  Message estimates(const std::vector<Key>& keys) const;
  Eigen::MatrixXd covariance(const std::vector<Key>& keys) const;

 private:
  struct Impl;
  int robot_;
  std::unique_ptr<Impl> impl_;
};

// The variables of `robot` that the separators touch, increasing.
std::vector<Key> SeparatorVariables(const std::vector<RelativePoseFactor>& separators, int robot);

// What the check of one robot pair finds.
struct PairConsistency {
  // The size of the largest pairwise-consistent set (a maximum clique): the pair confirms itself
  // with min_support, may be left to the robust solve with linked_min_support.
  int largest = 0;
  // What the pair keeps if it is kept (positions in the separators, increasing). Confirmed: one
  // largest set (among tied ones, the one the search finds first with the separators in canonical
  // order, graph/pose_graph.h: the same whatever order they are listed in). Below min_support:
  // every separator of some largest set, as the check cannot tell tied sets apart (two right
  // separators that agree against two wrong ones that agree: generated, 4 robots, 70 % injected
  // wrong pairs, seed 17, where the check kept the wrong two), and the robust solve tests them all
  // through the loop.
  std::vector<std::size_t> kept;
  // Per separator: how many members of `kept` it passes the pairwise test with (not itself).
  std::vector<int> support;
  // The largest pairwise-consistent set of the separators not in `kept` (positions, increasing):
  // the runner-up, which RobustDgsOptions::retest_groups tests again when the pair is kept.
  std::vector<std::size_t> runner_up;
};

// The check of one robot pair a < b, at robot a: `separators` are the factors between the two
// (in any order: the result, in positions of `separators`, does not depend on it), `a_map` a's map,
// `b_estimates` and `b_covariance` what b sent (its map's estimates of
// SeparatorVariables(separators, b) and their joint covariance; the covariance is ignored without
// options.map_uncertainty). Throws InvalidInputError when b's message does not hold exactly those
// variables or the covariance has the wrong size.
PairConsistency ConsistentSeparators(const std::vector<RelativePoseFactor>& separators,
                                     const SeparatorCheckMap& a_map, const Message& b_estimates,
                                     const Eigen::MatrixXd& b_covariance,
                                     const SeparatorConsistencyOptions& options);

// robust (empty, or one flag per factor of graph): the separators it marks are the ones checked
// (a separator it does not mark is kept untested: the odometry between two blocks of a split
// file); the intra-robot factors it marks (object measurements) are robust in each robot's own
// map too: the map is then its GNC-TLS estimate
// (robust/gnc.h, with `local`) and its covariances those of the weighted graph, so that a wrong
// association inside one robot's map does not make every separator of that robot disagree.
// Throws InvalidInputError (bad options, a mask of the wrong size) and what the local solves throw.
SeparatorConsistencyResult CheckSeparatorConsistency(const PoseGraph& graph,
                                                     const SeparatorConsistencyOptions& options,
                                                     const std::vector<bool>& robust = {},
                                                     const GncOptions& local = {});

// The one-to-one rule of object-object separators (SeparatorConsistencyOptions::
// one_to_one_objects) applied to weights after the check: among the separators `members` lists
// (factor positions) that pair an object of one robot with an object of another and weigh >= 0.5,
// taken in increasing r2 (ties: position), each that would pair a landmark with a second landmark
// of the other robot gets weight 0. `r2` holds r^T Omega r per factor (read at the members). A
// landmark's pairs with one robot are all separators of that robot pair, so the robot owning a
// pair's weights applies it to its own alone and gets the same weights. Returns how many it set to
// 0. Throws InvalidInputError when a member is out of range of factors, r2 or weights.
int KeepOneToOne(const std::vector<RelativePoseFactor>& factors,
                 const std::vector<std::size_t>& members, const std::vector<double>& r2,
                 std::vector<double>* weights);

// Whether factor i, an object-object separator, would pair a landmark with a second landmark of
// the other robot beside the members of weight >= 0.5 (false for any other factor).
bool BreaksOneToOne(const std::vector<RelativePoseFactor>& factors,
                    const std::vector<std::size_t>& members, const std::vector<double>& weights,
                    std::size_t i);

}  // namespace moslam
