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
// The agent composes one piece per job, each in its own file: the robot's part of the graph
// (local_graph.h), what it received (neighbour_inbox.h), its block of each linear stage
// (local_system.h), the sweep bookkeeping of the stopping rules (sweep_progress.h), the coarse
// correction of the two-level DGS (coarse_correction.h), the Gauss-Newton refinement
// (refinement.h) and conjugate gradients (conjugate_gradients.h); this class is the state machine
// and the messages. The subgraph holds every factor that touches one of the robot's variables:
// inner edges (both ends its own) and separators (one end another robot's). Ownership is the
// robot in each key. The anchor (first pose of robot 0, CONVENTIONS.md) is held at its initial
// value by the agent that owns it: it is not an unknown (eliminated, so it is exact in both
// stages).
//
// Flagged initialisation: in each stage a separator is used only once the other robot has
// solved in that stage (its messages say `initialised`). Without it, a separator is used as soon
// as some estimate of the neighbour arrived (the driver first exchanges initial estimates). An
// agent whose variables are not all connected, through inner edges, to the anchor, a prior or a
// usable separator cannot solve: iterate() then waits (returns false, changes nothing). In stages
// 1 and 2 (by sweeps) an agent solves the groups that are tied down and holds the others (beyond
// DGS.md, where the flag is one bit per robot): its messages then carry only the variables it has
// solved in the stage, a receiver uses a separator only once its foreign variable came in a
// message flagged initialised, and the agent reports an infinite change until every group is
// solved, so no stopping rule ends the stage before. Without it, a landmark whose only factors
// are separators (its own observation rejected by the robust solve) to a robot that reaches the
// anchor only through this robot's other variables deadlocked the two: each waited for the other.
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

#include "moslam/distributed/coarse_correction.h"
#include "moslam/distributed/conjugate_gradients.h"
#include "moslam/distributed/dgs_types.h"
#include "moslam/distributed/local_graph.h"
#include "moslam/distributed/local_system.h"
#include "moslam/distributed/messages.h"
#include "moslam/distributed/neighbour_inbox.h"
#include "moslam/distributed/refinement.h"
#include "moslam/distributed/sweep_progress.h"
#include "moslam/graph/pose_graph.h"

namespace moslam {

struct AgentOptions {
  double gamma = 1.0;                  // over-relaxation: x <- (1 - gamma) x_old + gamma x_new
  double refine_gamma = 1.0;           // the same for the refinement sweeps
  bool flagged_initialisation = true;
  bool weight_by_information = false;  // unit weights as the DGS reference

  // Throws InvalidInputError unless 0 < gamma < 2 and 0 < refine_gamma < 2.
  void validate() const;
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

  int robot() const { return graph_.robot(); }
  AgentState state() const { return state_; }
  // The robot's variables (anchor included), ordered.
  const std::vector<Key>& ownVariables() const { return graph_.own(); }
  // Foreign variables its separators touch (the neighbour table), and their owners.
  const std::set<Key>& neighbourVariables() const { return graph_.neighbourKeys(); }
  std::set<int> neighbourRobots() const { return graph_.neighbourRobots(); }
  // For each neighbouring robot, how many of its variables this robot needs.
  std::map<int, int> neighbourLinks() const { return graph_.neighbourLinks(); }
  // For each neighbouring robot, which of this robot's variables it needs.
  const std::map<int, std::vector<Key>>& sharedWith() const { return graph_.sharedWith(); }

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
  // the increments restart at 0 and the neighbours' increments are forgotten. scaleStep(f):
  // in kRefine, after the step's linear solve, the step becomes f (in (0, 1]) times itself, its
  // own increments and the neighbours' alike (a backtrack: costShare(true) and acceptStep() use
  // it; beginStep() restores 1). acceptStep(): in kRefine, applies the step's increments.
  // finishRefine(): kRefine -> kDone. Throw InvalidInputError when called in another state or
  // with a negative lambda or a factor outside (0, 1].
  void startRefine();
  void beginStep(double lambda);
  void scaleStep(double factor);
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
  // and res = -g start there); beginStep() switches back. In kRefine, or in kPose (the pose stage
  // by conjugate gradients: delta = 0 from the stage's current values, own and received, and res
  // = G0 - H x at them); InvalidInputError else.
  void startPreconditioner();
  double residualDot() const;
  void firstDirection();
  void nextDirection(double beta);
  double curvature();
  // ||p_r||: a robot's change in an iteration is |alpha| ||p_r|| (0 outside conjugate gradients).
  double directionNorm() const { return cg_active_ ? cg_.direction().norm() : 0.0; }
  void advance(double alpha);

  // The second level of the refinement's preconditioner (coarse_correction.h,
  // RefineCoarseSpace; dgs_driver.h, DgsOptions::Refinement::preconditioner). In a CG step
  // (after startPreconditioner()):
  //   refineCoarseReady():    this robot can take part (it can solve in this step)
  //   refineCoarseMatrix():   its rows of the step's coarse matrix P^T (H + damping) P, the basis
  //                           at the step's linearisation point (once per step)
  //   refineCoarseResidual(): P_r^T (res - H z)_r with its z and the neighbours' latest z
  //   applyRefineCoarse(y):   z += P y, to its z and its copies of the neighbours' z
  // InvalidInputError outside a CG step (and before refineCoarseMatrix() for the other two).
  bool refineCoarseReady() const;
  CoarseShare refineCoarseMatrix();
  Eigen::VectorXd refineCoarseResidual() const;
  void applyRefineCoarse(const std::map<int, Eigen::MatrixXd>& y);
  // The same by pieces of piece_poses poses (DgsOptions::Refinement::coarse_piece_poses > 0; in
  // a refinement step only): its kPieceMatrix, kPieceResidual, and z += P y from a
  // kPieceSolution. InvalidInputError as above, in the pose stage, or with piece_poses 0.
  CoarseMessage refinePieceMatrix(std::uint64_t piece_poses, std::uint32_t iteration);
  CoarseMessage refinePieceResidual(std::uint32_t iteration) const;
  void applyRefinePieces(const CoarseMessage& solution);

  // This robot's share of the cost F (see the top): at the current estimate, or (candidate) at
  // x Exp(delta) with the neighbours' latest increments. In kRefine (InvalidInputError else).
  double costShare(bool candidate) const;
  // ||delta||_2 over the robot's stacked increments (0 outside kRefine).
  double incrementNorm() const;
  // From now on this robot counts its separators to `robot` in costShare() (the other robot no
  // longer reports).
  void setUnresponsive(int robot) { refinement_.setUnresponsive(robot); }
  bool refined() const { return refinement_.started(); }

  ReceiveStatus receive(const Message& message);

  // One local solve of the current stage with the neighbour estimates held now. Returns false
  // (and changes nothing) when the robot cannot solve yet (flagged initialisation: no usable
  // separator reaches some of its variables). Throws InvalidInputError outside
  // kRotation/kPose/kRefine.
  bool iterate();
  // Messages with the current estimates of the variables each neighbouring robot needs
  // (empty outside kRotation/kPose/kRefine).
  std::vector<OutgoingMessage> outgoing() const;

  // Two-level DGS (beyond DGS.md; DgsOptions::coarse_correction in dgs_driver.h; the basis and
  // what share and apply compute: coarse_correction.h). coarseReady(absent): the last solve used
  // every separator except those to the `absent` robots (stopped answering: their variables stay
  // fixed), so the local normal matrix is the robot's whole diagonal block H_rr of the stage.
  // coarseShare(): its rows of the coarse system (InvalidInputError before a solve of stage 1 or
  // 2; the driver asks only once every robot is coarseReady). applyCoarse(y): the correction, to
  // its own unknowns and its copies of the neighbours' variables.
  bool coarseReady(const std::set<int>& absent = {}) const;
  CoarseShare coarseShare();
  void applyCoarse(const std::map<int, Eigen::MatrixXd>& y);

  // Iterations (solves) done in the current stage; whether it has solved in this stage.
  int iteration() const { return iteration_; }
  bool initialised() const { return progress_.initialised(); }
  // ||x_solve - x_old||_2 over the robot's stacked unknowns at its last solve (9 numbers per
  // variable in stage 1, 6 in stage 2 and in a refinement step); +infinity before the first solve
  // of a stage (of a refinement step).
  double lastChange() const { return progress_.lastChange(); }
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
  // Its copies of the neighbours' variables after startRefine() (each owner's increments applied
  // to the pose it sent: the owner's own estimate, bitwise, in the in-process driver); variables
  // never received are left out. Empty before the refinement.
  Values neighbourEstimates() const;
  // The stage-1 relaxed rotations (row by row), own variables.
  std::map<Key, Eigen::VectorXd> relaxedRotations() const;

  std::int64_t duplicatesIgnored() const { return inbox_.duplicates(); }
  std::int64_t staleIgnored() const { return inbox_.stale(); }

 private:
  DgsStage currentStage() const;
  bool usable(const Separator& s, DgsStage stage) const;
  // The separators the current stage can use; false when some group of unknowns is not anchored.
  // With `held` (stages 1 and 2 by sweeps): true as soon as one group is, `held` flagging the
  // unknowns of the groups that are not (empty when none is).
  bool solvable(DgsStage stage, std::vector<bool>& use, std::vector<bool>* held = nullptr) const;
  // Stages 1 and 2 by sweeps (not the refinement, not conjugate gradients): the groups of its
  // unknowns that are tied down are solved and sent first (see the top).
  bool solvesByGroups(DgsStage stage) const { return stage != DgsStage::kRefine && !cg_active_; }
  LocalSystem& system(DgsStage stage) { return stage == DgsStage::kRotation ? rotation_ : pose_; }
  const LocalSystem& system(DgsStage stage) const {
    return stage == DgsStage::kRotation ? rotation_ : pose_;
  }
  // The stage's terms into its system (stages 1 and 2).
  void prepareStage(DgsStage stage);
  // The right-hand side of the local solve with the neighbour values held now (after assembly):
  // G0 (conjugate gradients: the residual) - sum_s H_rs x_s.
  Eigen::MatrixXd localRhs(DgsStage stage) const;
  // G - sum_s H_rs x_s over the separators used, x_s the values held now.
  Eigen::MatrixXd subtractCouplings(DgsStage stage, Eigen::MatrixXd G) const;
  // The stage conjugate gradients run in (pose or refinement; InvalidInputError otherwise, and in
  // the refinement before beginStep()).
  DgsStage cgStage(const char* what) const;
  void requireRefine(const char* what) const;
  // Throws InvalidInputError "<what> in state <state><hint>" unless the agent is in `expected`.
  void requireState(AgentState expected, const char* what, const char* hint = "") const;
  // Start of a stage or of a linear step: not yet solved, no change measured.
  void resetProgress();
  // The step's increment of unknown i / of a neighbour variable (0 if none arrived).
  Vector6 ownIncrement(std::size_t i) const;
  Vector6 neighbourIncrement(int slot) const;
  Eigen::VectorXd stackedSweepValue() const;  // x_ stacked

  AgentOptions options_;
  LocalGraph graph_;
  NeighbourInbox inbox_;
  LocalSystem rotation_, pose_;  // the pose stage's system serves the refinement too
  StageCoarseSpace coarse_;
  Refinement refinement_;
  RefineCoarseSpace refine_coarse_;
  bool refine_coarse_built_ = false;
  ConjugateGradients cg_;
  SweepProgress progress_;

  AgentState state_ = AgentState::kIdle;
  int iteration_ = 0;  // solves in the current stage: the messages' iteration numbers
  std::vector<Eigen::VectorXd> x_;              // per unknown, StageDimension of the stage
  std::vector<bool> solved_;                    // stages 1 and 2: per unknown, solved in the stage
  std::vector<Eigen::VectorXd> before_coarse_;  // x_ before the coarse corrections since the
                                                // last solve (empty: none)
  std::vector<Eigen::VectorXd> relaxed_;        // stage-1 result kept for relaxedRotations()
  std::map<Key, Matrix3> R_hat_;                // stage-2 linearisation point (own + neighbours)
  // Refinement: whether the step is linearised and solved by conjugate gradients (and whether
  // this robot can solve in it).
  bool linearized_ = false;
  double lambda_ = 0.0;
  bool cg_active_ = false;
  bool can_solve_ = true;
  // Pose-stage conjugate gradients: the starting values, own (by unknown) and the neighbours'
  // (by slot).
  std::vector<Eigen::VectorXd> own_start_, pose_start_;
  double step_scale_ = 1.0;  // the refinement step's backtracking factor (scaleStep())
};

}  // namespace moslam
