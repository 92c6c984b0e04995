// One robot of the distributed Gauss-Seidel solver (shared/DGS.md), in the style of dpgo's
// PGOAgent: it owns its subgraph and its variables, knows which foreign variables it needs, and
// knows nothing about transport. A driver (or a network node) moves messages between agents:
//
//   RobotAgent agent(robot, subgraph, initial, anchor, options);
//   agent.startRotation();                 // stage 1 (chordal relaxation)
//   loop: for (auto& m : incoming) agent.receive(m);
//         agent.iterate();                 // one exact local solve, then x <- (1-g) x + g x_new
//         send agent.outgoing();           // estimates of its separator variables, per robot
//   agent.startPose();                     // project to SO(3); stage 2 (one pose step)
//   loop as above; agent.finish();         // estimate() is final
//
// The subgraph holds every factor that touches one of the robot's variables: inner edges (both
// ends its own) and separators (one end another robot's). Ownership is the robot in each key.
// The anchor (first pose of robot 0, CONVENTIONS.md) is held at its initial value by the agent
// that owns it: it is not an unknown (eliminated, so it is exact in both stages).
//
// Flagged initialisation: in each stage a separator is used only once the other robot has
// solved in that stage (its messages say `initialised`). Without it, a separator is used as soon
// as some estimate of the neighbour arrived (the driver first exchanges initial estimates). An
// agent whose variables are not all connected, through inner edges, to the anchor, a prior or a
// usable separator cannot solve: iterate() then waits (returns false, changes nothing).
//
// Messages: receive() keeps, per stage and sender, only messages newer than the last accepted
// (iteration strictly larger); duplicates and older (stale, reordered) messages are counted and
// ignored, as are messages of a stage the agent has left.
//
// Refinement (beyond DGS.md): Gauss-Newton on the SE(3) cost F = sum 1/2 r^T Omega r
// (graph/factors.h), each linear step H delta = -g solved by the same robot-by-robot sweeps:
//
//   agent.startRefine();          // from kDone: x = the two-stage estimate; the neighbours'
//                                 // poses are rebuilt from the pose stage's messages
//   per Gauss-Newton step:
//     agent.beginStep(lambda);    // linearise at x (unless only lambda changed), delta = 0
//     sweeps: receive / iterate / outgoing as above (DgsStage::kRefine: the increments delta);
//             iterate() solves (H_rr + lambda diag(H_rr)) delta_r = -g_r - sum_s H_rs delta_s
//             with the neighbours' latest deltas (0 until received in this step)
//     agent.costShare(true);      // its share of F at x Exp(delta), for the global decision
//     agent.acceptStep();         // x <- x Exp(delta), the neighbours' copies likewise
//   agent.finishRefine();         // kDone; estimate() is the refined x
//
// Only increments cross the network during a step; the neighbours' poses are not re-sent: each
// robot applies the accepted increments it received to its copy of the neighbours' poses, the
// same operation on the same numbers as their owners (bitwise equal in the in-process driver).
// The anchor is not an unknown (its increment is 0). The cost F is the sum over robots of
// costShare(): every inner factor and prior, and each separator counted once, by the robot with
// the lower id (or by the one left when the other stops answering, setUnresponsive()).
// Separators to a neighbour whose pose the robot never received are left out of the refinement.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <limits>
#include <map>
#include <memory>
#include <set>
#include <vector>

#include "moslam/distributed/dgs_types.h"
#include "moslam/distributed/messages.h"
#include "moslam/graph/pose_graph.h"

namespace moslam {

class BlockLeastSquares;
struct LinearTerm;

struct AgentOptions {
  double gamma = 1.0;                  // over-relaxation: x <- (1 - gamma) x_old + gamma x_new
  double refine_gamma = 1.0;           // the same for the refinement sweeps
  bool flagged_initialisation = true;
  bool weight_by_information = false;  // unit weights as the DGS reference

  // Throws InvalidInputError unless 0 < gamma < 2 and 0 < refine_gamma < 2.
  void validate() const;
};

enum class ReceiveStatus { kAccepted, kDuplicate, kStale };

// One robot's rows of the coarse system of the two-level DGS (RobotAgent::coarseShare()):
// k = 3 unknowns per robot and 3 right-hand sides in stage 1, k = 6 and 1 in stage 2.
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

// A message to one neighbouring robot.
struct OutgoingMessage {
  int to = 0;
  Message message;
};

class RobotAgent {
 public:
  // `subgraph`: every factor touching a variable of `robot` (each must touch one; separators
  // to other robots included). `initial`: initial values; variables of `robot` missing from it
  // start at the identity. `anchor`: the global gauge variable, pinned if this robot owns it.
  // Throws InvalidInputError on a factor that touches none of the robot's variables or bad
  // options, UnderdeterminedError when the robot owns no variable.
  RobotAgent(int robot, const PoseGraph& subgraph, const Values& initial, const Key& anchor,
             const AgentOptions& options = {});
  ~RobotAgent();
  RobotAgent(const RobotAgent&) = delete;
  RobotAgent& operator=(const RobotAgent&) = delete;

  int robot() const { return robot_; }
  AgentState state() const { return state_; }
  // The robot's variables (anchor included), ordered.
  const std::vector<Key>& ownVariables() const { return own_; }
  // Foreign variables its separators touch (the neighbour table), and their owners.
  const std::set<Key>& neighbourVariables() const { return neighbour_keys_; }
  std::set<int> neighbourRobots() const;
  // For each neighbouring robot, how many of its variables this robot needs.
  std::map<int, int> neighbourLinks() const;
  // For each neighbouring robot, which of this robot's variables it needs.
  const std::map<int, std::vector<Key>>& sharedWith() const { return shared_with_; }

  // Stage transitions. startRotation(): from kIdle; own estimate starts at the initial
  // rotations. startPose(): from kRotation; projects the own and the received neighbour
  // rotations to SO(3) (the linearisation point) and starts the deltas at 0. finish(): from
  // kPose. Throw InvalidInputError when called in another state.
  void startRotation();
  void startPose();
  void finish();

  // Refinement (see the top of this file). startRefine(): from kDone, once, after the pose
  // stage. beginStep(lambda >= 0): in kRefine; relinearises at the current estimate after
  // startRefine() or acceptStep(), else keeps the linearisation and only changes the damping;
  // the increments restart at 0 and the neighbours' increments are forgotten. acceptStep():
  // in kRefine, applies the step's increments. finishRefine(): kRefine -> kDone. Throw
  // InvalidInputError when called in another state or with a negative lambda.
  void startRefine();
  void beginStep(double lambda);
  void acceptStep();
  void finishRefine();
  // Conjugate gradients on the step's system (H + lambda diag(H_rr)) delta = -g: the sweeps then
  // apply a preconditioner M^-1 to the residual instead of updating delta directly.
  //   startPreconditioner():  z = 0 and the neighbours' z forgotten; then sweeps on H z = res
  //                           (Gauss-Seidel forward then backward: symmetric block Gauss-Seidel,
  //                           SSOR with refine_gamma; one Jacobi sweep: block Jacobi)
  //   residualDot():          res_r . z_r, this robot's part of res . z
  //   firstDirection(), nextDirection(beta): p = z (+ beta p); the neighbours' p likewise from
  //                           the z they sent (no extra message)
  //   curvature():            p_r . (H p)_r with (H p)_r = H_rr p_r + sum_s H_rs p_s
  //   advance(alpha):         delta += alpha p, res -= alpha H p (the neighbours' delta copies
  //                           too), so the step's increments never need to be sent
  // The first startPreconditioner() of a step switches the step to conjugate gradients (delta
  // and res = -g start there); beginStep() switches back. In kRefine (InvalidInputError else).
  void startPreconditioner();
  double residualDot() const;
  void firstDirection();
  void nextDirection(double beta);
  double curvature();
  void advance(double alpha);

  // This robot's share of the cost F (see the top): at the current estimate, or (candidate) at
  // x Exp(delta) with the neighbours' latest increments. In kRefine (InvalidInputError else).
  double costShare(bool candidate) const;
  // ||delta||_2 over the robot's stacked increments (0 outside kRefine).
  double incrementNorm() const;
  // From now on this robot counts its separators to `robot` in costShare() (the other robot no
  // longer reports).
  void setUnresponsive(int robot);
  bool refined() const { return refined_; }

  ReceiveStatus receive(const Message& message);

  // One local solve of the current stage with the neighbour estimates held now. Returns false
  // (and changes nothing) when the robot cannot solve yet (flagged initialisation: no usable
  // separator reaches some of its variables). Throws InvalidInputError outside
  // kRotation/kPose/kRefine.
  bool iterate();
  // Messages with the current estimates of the variables each neighbouring robot needs
  // (empty outside kRotation/kPose/kRefine).
  std::vector<OutgoingMessage> outgoing() const;

  // Two-level DGS (beyond DGS.md; DgsOptions::coarse_correction in dgs_driver.h): a Galerkin
  // correction x_i += P_i y_r over the motions of whole robots, the slow modes of the sweeps
  // (each robot's block is solved exactly; what the sweeps are slow at is moving a whole robot
  // against the others). For every variable i of robot r:
  //   stage 1: X_i += X_i Y_r, Y_r 3x3 (X = R^T: R += Y_r^T R, a linear map of the whole robot;
  //            the chordal residual of an edge inside the robot only scales by it)
  //   stage 2: dtheta_i += R_hat_i^T w_r, t_i += tau_r + w_r x (t_i - c_r), y_r = (w_r, tau_r):
  //            a rigid motion of the robot about its centre c_r (CoarseShare::center; edges
  //            inside the robot change only by w_r x their residual)
  // coarseReady(absent): the last solve used every separator except those to the `absent`
  // robots (stopped answering: their variables stay fixed), so the local normal matrix is the
  // robot's whole diagonal block H_rr of the stage. coarseShare(): its rows of the coarse system
  // (P^T H P) y = P^T (g - H x) at the current estimates, own and received, for the separators
  // its last solve used (InvalidInputError before a solve of stage 1 or 2; the driver asks only
  // once every robot is coarseReady). applyCoarse(y): adds P_i y_robot to the own unknowns and
  // to the received copies of the neighbours' variables (robots missing from y: 0), every y in
  // this robot's basis (stage 2: centred on its c_r, as coarseShare() computed it; the estimates
  // must not change in between): the same motion of the same numbers as their owners apply, so
  // no estimate has to be sent again.
  bool coarseReady(const std::set<int>& absent = {}) const;
  CoarseShare coarseShare();
  void applyCoarse(const std::map<int, Eigen::MatrixXd>& y);

  // Iterations (solves) done in the current stage; whether it has solved in this stage.
  int iteration() const { return iteration_; }
  bool initialised() const { return initialised_; }
  // ||x_solve - x_old||_2 over the robot's stacked unknowns at its last solve (9 numbers per
  // variable in stage 1, 6 in stage 2 and in a refinement step); +infinity before the first solve
  // of a stage (of a refinement step).
  double lastChange() const { return last_change_; }
  // The a-posteriori distance bound of StageStopping::kErrorBound (dgs_types.h): gamma * c *
  // rho / (1 - rho) over the stage's non-zero changes c (a solve that changes nothing had no new
  // input and is skipped), c the last of them, rho the largest sqrt(c_k / c_{k-2}) over the last
  // `window` of them; +infinity with fewer than window + 2 of them or a ratio >= 1; 0 when the
  // last window + 2 solves changed nothing. window in [1, 64]; throws InvalidInputError otherwise.
  double errorBound(int window) const;

  // The current estimate of the robot's variables: initial values (kIdle), projected rotations
  // with zero translation (kRotation), R_hat Exp(dtheta), t (kPose, kDone), the last accepted
  // refinement estimate (kRefine, kDone after it). The anchor is always its initial value.
  Values estimate() const;
  // The stage-1 relaxed rotations (row by row), own variables.
  std::map<Key, Eigen::VectorXd> relaxedRotations() const;

  std::int64_t duplicatesIgnored() const { return duplicates_; }
  std::int64_t staleIgnored() const { return stale_; }

 private:
  struct Separator {
    std::size_t factor;  // index into factors_
    Key own, foreign;
    int foreign_robot;
    int slot = 0;        // the foreign variable's index in neighbour_list_
  };
  struct StageInbox {
    // The latest estimate received per neighbour variable (by slot), and whether one arrived.
    std::vector<Eigen::VectorXd> values;
    std::vector<char> has;
    std::map<int, std::int64_t> last_iteration;
    std::set<int> initialised_robots;
    const Eigen::VectorXd* get(int slot) const {
      return has.empty() || !has[static_cast<std::size_t>(slot)]
                 ? nullptr
                 : &values[static_cast<std::size_t>(slot)];
    }
    void forget() { std::fill(has.begin(), has.end(), 0); }
  };

  DgsStage currentStage() const;
  void prepareStage(DgsStage stage);
  StageInbox& inbox(DgsStage stage);
  bool usable(const Separator& s, DgsStage stage) const;
  Eigen::MatrixXd neighbourValue(int slot, DgsStage stage) const;
  // A_own^T W A_foreign of a separator whose linear term (terms_[sep.factor]) is built.
  Eigen::MatrixXd couplingBlock(const Separator& sep) const;
  void requireRefine(const char* what) const;
  // Throws InvalidInputError "<what> in state <state><hint>" unless the agent is in `expected`.
  void requireState(AgentState expected, const char* what, const char* hint = "") const;
  // Start of a stage or of a linear step: not yet solved, no change measured.
  void resetProgress();
  // Which separators the current stage can use; false when some block is not anchored yet.
  bool solvable(DgsStage stage, std::vector<bool>& use) const;
  // Builds and factorizes the normal matrix (and G0_) unless cached for `use`.
  void assemble(DgsStage stage, const std::vector<bool>& use);
  // The right-hand side of the local solve with the neighbour values held now (after assemble).
  Eigen::MatrixXd localRhs(DgsStage stage) const;
  // The coarse basis P_i (module comment above) of a variable with stage value x; R_hat: its
  // linearisation rotation, center: the point the rotations turn about (stage 2 only).
  static Eigen::MatrixXd CoarseBasis(DgsStage stage, const Eigen::VectorXd& x,
                                     const Matrix3* R_hat, const Eigen::Vector3d& center);
  // CoarseBasis of variable `key` (own or a neighbour's copy) with stage value x in the current
  // stage; frozen: its translation when the stage-2 basis was frozen (unused in stage 1).
  Eigen::MatrixXd coarseBasisOf(const Key& key, const Eigen::VectorXd& x,
                                const Eigen::Vector3d& frozen) const;
  // Stage 2: fixes the coarse basis at the first coarseShare() of the stage, so every
  // correction of the stage works in one subspace (the two-level contraction): the lever arms
  // are the translations then (own and copies) and c_r their mean.
  void freezeCoarseBasis();
  // The refinement's linear terms at the current estimate (GN: A = dr/dx, C = r, W = Omega).
  void linearizeRefine();
  const SE3* knownPose(const Key& key) const;  // own or a neighbour's copy; nullptr if unknown
  // The step's increment of unknown i / of a neighbour variable (0 if none arrived).
  Vector6 ownIncrement(std::size_t i) const;
  Vector6 neighbourIncrement(int slot) const;
  Eigen::VectorXd stackedSweepValue() const;  // x_ stacked

  int robot_;
  AgentOptions options_;
  Key anchor_;
  bool owns_anchor_ = false;
  SE3 anchor_pose_;
  std::vector<RelativePoseFactor> factors_;
  std::vector<PriorFactor> priors_;
  std::vector<std::size_t> inner_;
  std::vector<Separator> separators_;
  std::vector<Key> own_;
  std::vector<Key> unknowns_;  // own_ without the anchor
  std::map<Key, int> unknown_index_;
  std::set<Key> neighbour_keys_;
  std::vector<Key> neighbour_list_;  // neighbour_keys_ in order: the slots
  std::map<Key, int> neighbour_slot_;
  std::map<int, std::vector<Key>> shared_with_;
  // Components of the unknowns through inner edges: whether each is tied to the anchor or a
  // prior, and its separators.
  std::vector<int> component_of_;  // per unknown
  std::vector<bool> component_fixed_;
  std::vector<std::vector<std::size_t>> component_separators_;
  Values initial_;  // own variables

  AgentState state_ = AgentState::kIdle;
  int iteration_ = 0;
  bool initialised_ = false;
  double last_change_ = std::numeric_limits<double>::infinity();
  std::vector<double> recent_changes_;  // the stage's last non-zero changes, oldest first (<= 66)
  int zero_changes_ = 0;                // solves since the last non-zero change
  std::vector<Eigen::VectorXd> x_;              // per unknown, StageDimension of the stage
  std::vector<Eigen::VectorXd> before_coarse_;  // x_ before the coarse corrections since the
                                                // last solve (empty: none)
  // Stage 2's frozen coarse basis (freezeCoarseBasis): translations per unknown and per
  // neighbour slot, and their centre.
  bool coarse_frozen_ = false;
  std::vector<Eigen::Vector3d> coarse_ref_, coarse_ref_copy_;
  Eigen::Vector3d coarse_centre_ = Eigen::Vector3d::Zero();
  std::vector<Eigen::VectorXd> relaxed_;        // stage-1 result kept for relaxedRotations()
  std::map<Key, Matrix3> R_hat_;                // stage-2 linearisation point (own + neighbours)
  std::map<DgsStage, StageInbox> inboxes_;
  // The current stage's terms (constant within a stage: stage 2 is linearised once), per factor
  // and prior; per separator, A_own^T W A_foreign (its right-hand side is linear in the
  // neighbour's estimate). The factorization is reused while the usable separators stay the same.
  std::vector<LinearTerm> terms_, prior_terms_;
  std::vector<Eigen::MatrixXd> coupling_;
  Eigen::MatrixXd anchor_value_;
  std::vector<bool> cached_use_;
  bool factorized_ = false;
  Eigen::MatrixXd G0_;
  std::vector<Eigen::Index> separator_row_;  // per separator: row of its own end, -1: unused
  std::unique_ptr<BlockLeastSquares> rotation_problem_, pose_problem_;
  std::int64_t duplicates_ = 0, stale_ = 0;

  // Refinement: the own estimate (anchor included), the copies of the neighbours' poses (by
  // slot; pose_known_: received), the damping, and the diagonal of each unknown's block of H.
  bool refined_ = false;
  bool linearized_ = false;
  double lambda_ = 0.0;
  Values pose_;
  std::vector<SE3> neighbour_pose_;
  std::vector<char> pose_known_;
  std::vector<Eigen::VectorXd> hessian_diagonal_;
  std::set<int> unresponsive_;
  // Conjugate gradients (stacked over unknowns_, 6 per unknown) and the neighbours' copies.
  bool cg_ = false;
  bool can_solve_ = true;
  Eigen::VectorXd cg_delta_, cg_res_, cg_p_, cg_q_;
  std::vector<Vector6> neighbour_p_, neighbour_delta_;  // by slot
};

}  // namespace moslam
