// The robot's side of the two-level DGS (DgsOptions::coarse_correction, beyond DGS.md): a Galerkin
// correction x_i += P_i y_r over the motions of whole robots, the slow modes of the sweeps (each
// robot's block is solved exactly; what the sweeps are slow at is moving a whole robot against
// the others). For every variable i of robot r:
//   stage 1: X_i += X_i Y_r, Y_r 3x3 (X = R^T: R += Y_r^T R, a linear map of the whole robot;
//            the chordal residual of an edge inside the robot only scales by it)
//   stage 2: dtheta_i += R_hat_i^T w_r, t_i += tau_r + w_r x (t_i - c_r), y_r = (w_r, tau_r):
//            a rigid motion of the robot about its centre c_r (CoarseShare::center; edges
//            inside the robot change only by w_r x their residual)
// share(): the robot's rows of the coarse system (P^T H P) y = P^T (g - H x) at the current
// estimates, own and received, for the separators the last solve used. apply(y): adds P_i y to the
// own unknowns and to the received copies of the neighbours' variables (robots missing from y:
// 0), every y in this robot's basis (stage 2: centred on its c_r, as share() computed it; the
// estimates must not change in between): the same motion of the same numbers as their owners
// apply, so no estimate has to be sent again. The stage-2 basis is frozen at the stage's first
// share (lever arms t_i - c_r of that moment), so every correction works in one subspace.
#pragma once

#include <Eigen/Core>
#include <map>
#include <vector>

#include "moslam/distributed/dgs_types.h"
#include "moslam/distributed/local_graph.h"
#include "moslam/distributed/local_system.h"
#include "moslam/distributed/messages.h"
#include "moslam/distributed/neighbour_inbox.h"
#include "moslam/distributed/refinement.h"

namespace moslam {

// One robot's rows of the coarse system: k = 3 unknowns per robot and 3 right-hand sides in
// stage 1, k = 6 and 1 in stage 2.
struct CoarseShare {
  Eigen::MatrixXd diagonal;                 // k x k: P_r^T H_rr P_r
  std::map<int, Eigen::MatrixXd> coupling;  // per neighbouring robot s: P_r^T H_rs P_s (k x k)
  Eigen::MatrixXd residual;                 // k x ncols: P_r^T (g - H x)_r
  // Stage 2: the point c_r the robot's coarse rotations turn about (the mean of its
  // translations; a basis centred on the robot keeps the coarse system well conditioned far from
  // the origin). Every block, the neighbours' columns included, is in this robot's basis
  // (centred on c_r); the coordinator moves them to the neighbours' centres. Stage 1: zero.
  Eigen::Vector3d center = Eigen::Vector3d::Zero();
};

class StageCoarseSpace {
 public:
  // `graph` must outlive it.
  explicit StageCoarseSpace(const LocalGraph& graph) : graph_(graph) {}

  // A new stage: the stage-2 basis is frozen again at the next share().
  void reset() { frozen_ = false; }
  bool frozen() const { return frozen_; }

  // `x`: the own unknowns' stage values; `rhs`: the local right-hand side with the neighbour values
  // held now (g - sum_s H_rs x_s); `R_hat`: stage 2's linearisation rotations (own and neighbours').
  CoarseShare share(DgsStage stage, const std::vector<Eigen::VectorXd>& x,
                    const Eigen::MatrixXd& rhs, const LocalSystem& system,
                    const NeighbourInbox& inbox, const std::map<Key, Matrix3>& R_hat);
  // Applies y (per robot, k x ncols, in this robot's basis) to `x` and to the inbox's copies.
  // Throws InvalidInputError in stage 2 before share().
  void apply(DgsStage stage, const std::map<int, Eigen::MatrixXd>& y,
             std::vector<Eigen::VectorXd>& x, NeighbourInbox& inbox,
             const std::map<Key, Matrix3>& R_hat) const;

 private:
  // P_i of a variable with stage value x (stage 2: its R_hat and lever arm about the centre).
  static Eigen::MatrixXd Basis(DgsStage stage, const Eigen::VectorXd& x, const Matrix3* R_hat,
                               const Eigen::Vector3d& lever);
  Eigen::MatrixXd basisOf(DgsStage stage, const Key& key, const Eigen::VectorXd& x,
                          const Eigen::Vector3d& frozen,
                          const std::map<Key, Matrix3>& R_hat) const;
  void freeze(const std::vector<Eigen::VectorXd>& x, const NeighbourInbox& inbox);

  const LocalGraph& graph_;
  bool frozen_ = false;
  std::vector<Eigen::Vector3d> ref_, ref_copy_;  // frozen translations: own, neighbours (by slot)
  Eigen::Vector3d centre_ = Eigen::Vector3d::Zero();
};

}  // namespace moslam

namespace moslam {

// The second level of the refinement's preconditioner (DgsOptions::Refinement::
// coarse_preconditioner): the same coarse space, one rigid motion y = (w, tau) of each robot
// about its centre c_r, in the refinement's unknowns, the right increments x_i Exp(delta_i):
//   delta_i = Ad(x_i^-1) [I 0; c_r^ I] y,
// the first-order increment of x_i moved by the world-frame rotation w about c_r and the
// translation tau. The basis is taken at the step's linearisation point and the robot's centre
// (the mean of its translations), for its unknowns and its known neighbour copies alike (the
// neighbours' columns in this robot's basis; CoarseSystem moves them to their own centres).
//
// By pieces (DgsOptions::Refinement::coarse_piece_poses = L > 0, the refinement only): one rigid
// motion per piece of the robot instead (CoarsePieceOf: poses by index / L, the robot's objects
// one piece), so that a run of the chain can turn against the rest, the slow mode of long chains
// (README, "What a richer coarse space would give"). Every column is computed about the robot's
// reference c_r (the mean of its translations) and sent with each piece's centre;
// PieceCoarseSystem (coarse_system.h) moves them to the pieces' centres. The piece of a neighbour
// variable follows from its key, so no piece map crosses the network.
class RefineCoarseSpace {
 public:
  // The basis at the current estimate of `refinement`: one piece per robot (piece_poses 0) or
  // pieces of piece_poses poses.
  void build(const LocalGraph& graph, const Refinement& refinement, std::uint64_t piece_poses = 0);
  // The same coarse space in the pose stage's unknowns (dtheta, t) (DgsOptions::pose_solver =
  // conjugate gradients): dtheta_i = R_hat_i^T w, t_i += tau, the robot's motion as a whole
  // without lever arms. With the lever arms of the flagged sweeps the conjugate gradients start
  // from (t_i += w x (t_i - c_r) + tau, c_r the mean translation), tried with that start (commit
  // 7b22866) and not kept: about as many graphs took more sweeps as fewer at eta 1e-2 (without ->
  // with: sphere2500 in 16 robots 205 -> 157, in 64 215 -> 243, city10000 in 16 373 -> 395,
  // input_M3500_g2o in 4 237 -> 191).
  void buildPoseStage(const LocalGraph& graph, const std::map<Key, Matrix3>& R_hat);
  // The robot's rows of the coarse matrix P^T (H + damping) P of the step's system, as assembled
  // in `system`: diagonal, couplings to the neighbouring robots, centre (no residual).
  CoarseShare matrix(const LocalGraph& graph, const LocalSystem& system) const;
  // P_r^T r for the robot's part r of a residual (stacked as the system's unknowns).
  Eigen::VectorXd project(const LocalGraph& graph, const LocalSystem& system,
                          const Eigen::VectorXd& r) const;
  // z_i += P_i y_r for the own unknowns (`z`, per unknown) and for the neighbours' copies of z in
  // `inbox` (the CG's stage; a copy not received yet counts as 0): the same move as their owners.
  void apply(const LocalGraph& graph, DgsStage stage, const std::map<int, Eigen::MatrixXd>& y,
             std::vector<Eigen::VectorXd>& z, NeighbourInbox& inbox) const;

  // By pieces (after build() with piece_poses > 0): the robot's kPieceMatrix (its rows of
  // P^T (H + damping) P), its kPieceResidual (P_p^T r per piece) and z += P y from a
  // kPieceSolution (y about c_r; pieces missing from it: 0). InvalidInputError without pieces.
  bool byPieces() const { return piece_poses_ > 0; }
  CoarseMessage pieceMatrix(const LocalGraph& graph, const LocalSystem& system,
                            std::uint32_t iteration) const;
  CoarseMessage pieceResidual(const LocalGraph& graph, const LocalSystem& system,
                              const Eigen::VectorXd& r, std::uint32_t iteration) const;
  void applyPieces(const LocalGraph& graph, DgsStage stage, const CoarseMessage& solution,
                   std::vector<Eigen::VectorXd>& z, NeighbourInbox& inbox) const;

 private:
  void requirePieces(const char* what) const;

  std::vector<Matrix6> own_;             // P_i per unknown
  std::vector<Matrix6> neighbour_;       // per slot (zero when unknown or the anchor)
  std::vector<char> neighbour_known_;
  Eigen::Vector3d centre_ = Eigen::Vector3d::Zero();
  std::uint64_t piece_poses_ = 0;
  std::vector<std::uint32_t> own_piece_, neighbour_piece_;  // by pieces: per unknown, per slot
  std::map<std::uint32_t, Eigen::Vector3d> piece_centre_;   // the own pieces' centres
};

// The piece of a variable in the refinement's coarse space by pieces: a pose's index / piece_poses
// (at most kObjectCoarsePiece - 1), kObjectCoarsePiece for every object landmark of the robot.
inline constexpr std::uint32_t kObjectCoarsePiece = 0xFFFFFFFFu;
std::uint32_t CoarsePieceOf(const Key& key, std::uint64_t piece_poses);

}  // namespace moslam
