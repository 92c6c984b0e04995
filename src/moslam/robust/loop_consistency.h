// Pairwise consistency of loop closures (PCM: Mangelson, Dominic, Eustice and Vasudevan, ICRA
// 2018): the loop two loop closures close through the map(s) they join, and the check of one
// robot's own loop closures through its odometry, as Kimera-RPGO runs PCM on a single robot.
//
// Two loop closures i and j, each a factor from a variable A to a variable B with measurement z
// (B ~ A z), close the loop
//     L_ij = z_i^-1 (A_i^-1 A_j) z_j (B_j^-1 B_i),
// the identity when both are right (for any orientation of either: it goes b_i -> a_i -> a_j ->
// b_j -> b_i). With e = Log(L_ij) (tangent order of CONVENTIONS.md) and Sigma_e its first-order
// covariance from z_i, z_j (their information's inverse) and the joint covariances of (A_i, A_j)
// and of (B_i, B_j) in the map(s) that relate them, they are consistent when
//     e^T Sigma_e^-1 e <= threshold,
// chi-square with 6 degrees of freedom when the informations are right (Mangelson et al. eq. 7).
// The drift between the two loop closures' variables is in the test: two right loop closures far
// apart in a drifting map still agree.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <map>
#include <vector>

#include "moslam/geometry/se3.h"
#include "moslam/graph/pose_graph.h"

namespace moslam {

// One loop closure as an end of a loop: its measurement from A to B, its covariance, and the
// estimates of A and B in the map(s) the loop goes through.
struct LoopEnd {
  SE3 z;
  Matrix6 sigma_z;
  SE3 A, B;
};
using Matrix12 = Eigen::Matrix<double, 12, 12>;

// e^T Sigma_e^-1 e of the loop of i and j (above); SA and SB are the joint covariances of
// (A_i, A_j) and of (B_i, B_j) (right perturbations), taken as independent of each other.
// Infinite when Sigma_e is not positive definite.
double LoopStatistic(const LoopEnd& i, const LoopEnd& j, const Matrix12& SA, const Matrix12& SB);

// One robot's odometry chained along its stretches without a gap. Its odometry is the factor
// between each pose and the next index (either way round; the first when there are several), among
// the factors `not_odometry` does not mark (one flag per factor, or empty: none marked); a factor
// under test (a robust mask's) is no odometry, so a marked factor that is the only one between two
// consecutive poses leaves a gap. Per pose: its stretch, its pose T chained from the stretch's
// first pose (the identity), and, with `uncertainty`, by first-order propagation of the odometry's
// covariances (the inverse of its information) the joint covariance of two poses of a stretch, its
// first pose fixed: exactly solver/marginals.h's on the odometry-only graph. With G = Ad(T^-1) and S the sum over the steps
// k before a pose of Ad(T_{k+1}) Sigma_k Ad(T_{k+1})^T, Cov(p, q) = G_p S_min(p,q) G_q^T.
// Throws InvalidInputError when the graph's poses belong to more than one robot, an odometry
// factor's information is not positive definite, or not_odometry is neither empty nor one flag per
// factor.
class OdometryChain {
 public:
  OdometryChain(const PoseGraph& graph, bool uncertainty,
                const std::vector<bool>& not_odometry = {});
  bool has(const Key& k) const;  // a pose of the graph (of its robot)
  // InvalidInputError for a key that is not a pose of the graph:
  int stretch(const Key& k) const;
  const SE3& pose(const Key& k) const;
  // (p, q): 12 x 12, zero without uncertainty. InvalidInputError when not on one stretch.
  Matrix12 joint(const Key& p, const Key& q) const;

 private:
  struct Node {
    int stretch = 0;
    SE3 T;
    Matrix6 G = Matrix6::Identity();
    Matrix6 S = Matrix6::Zero();
  };
  const Node& node(const Key& k) const;
  int robot_ = -1;  // whose poses
  std::map<std::uint64_t, Node> nodes_;
};

struct OdometryCheckOptions {
  double threshold = 22.46;  // chi-square, 6 degrees of freedom, at 0.999
  // Fewer loop closures than this agreeing pairwise do not confirm one another: the check then
  // decides nothing (every loop closure is left to the robust solve).
  int min_support = 3;
  // false: the odometry taken as exact (Sigma_e from z_i and z_j alone), for graphs whose
  // information does not describe their noise.
  bool odometry_uncertainty = true;
  // Throws InvalidInputError naming the bad field.
  void validate() const;
};

struct OdometryCheckResult {
  std::vector<bool> kept;  // per factor of the graph (true for every factor not checked)
  // Per factor of the graph: whether it is a loop closure checked whose two poses the odometry
  // joins (one stretch of the OdometryChain). What a map built to judge other factors leaves out,
  // its odometry holding that relative pose with the drift in its covariance
  // (distributed/robust_dgs.h: the robots' maps of the separator check); a loop closure across a
  // gap in the odometry, the only link between two stretches, is false.
  std::vector<bool> along_odometry;
  int loop_closures = 0;   // checked
  int rejected = 0;
  int largest = 0;           // the largest pairwise-consistent set (a maximum clique)
  bool exact = true;         // the maximum clique search finished (max_clique.h)
  long long pairs = 0;       // pairs tested
  long long untestable = 0;  // pairs whose loop crosses a gap in the odometry: taken as consistent
  // Whether factor i belongs in a map built to judge other factors: kept, and not along the
  // odometry (the rule of the separator check's maps, in-process and in the robot programs).
  bool inMap(std::size_t i) const { return kept[i] && !along_odometry[i]; }
};

// One robot's loop closures checked pairwise through its odometry, before the robust solve.
// The graph's poses must be one robot's (InvalidInputError else). Its OdometryChain, of the
// factors `robust` does not mark, is the map A = B of the loops, with its joint covariances (zero
// without odometry_uncertainty). The loop closures checked are the factors `robust` marks (one flag
// per factor) that join two poses; a pair whose loop crosses a gap in the odometry cannot be tested
// and counts as consistent. The largest pairwise-consistent set is kept when it has min_support
// members, the other loop closures rejected. The two stretches of odometry in a loop are taken as
// independent (they may overlap). Pairs: n^2 / 2 for n loop closures.
OdometryCheckResult CheckLoopClosuresByOdometry(const PoseGraph& graph,
                                                const std::vector<bool>& robust,
                                                const OdometryCheckOptions& options = {});

// The same check run by each robot of a team on its own loop closures (the factors `robust` marks
// that join two of its poses), through its own odometry: what it needs is its own, nothing crosses
// the network. Factors between two robots are kept and not checked (separator_consistency.h checks
// those). The counts add over the robots; largest is the largest of their sets, exact whether
// every search finished. A robot with no such loop closure costs nothing.
OdometryCheckResult CheckEachRobotsLoopClosures(const PoseGraph& graph,
                                                const std::vector<bool>& robust,
                                                const OdometryCheckOptions& options = {});

}  // namespace moslam
