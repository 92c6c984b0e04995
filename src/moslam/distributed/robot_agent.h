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
// A refinement stage (Gauss-Newton on the SE(3) cost, each linear step solved by the same
// sweeps) fits the same shape: a per-stage term builder (two_stage_terms.h) on bs = 6 unknowns,
// the same neighbour tables and messages (DgsStage::kRefine, 6 numbers).
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
  bool flagged_initialisation = true;
  bool weight_by_information = false;  // unit weights as the DGS reference

  // Throws InvalidInputError unless 0 < gamma < 2.
  void validate() const;
};

enum class ReceiveStatus { kAccepted, kDuplicate, kStale };

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

  ReceiveStatus receive(const Message& message);

  // One local solve of the current stage with the neighbour estimates held now. Returns false
  // (and changes nothing) when the robot cannot solve yet (flagged initialisation: no usable
  // separator reaches some of its variables). Throws InvalidInputError outside kRotation/kPose.
  bool iterate();
  // Messages with the current estimates of the variables each neighbouring robot needs
  // (empty outside kRotation/kPose).
  std::vector<OutgoingMessage> outgoing() const;

  // Iterations (solves) done in the current stage; whether it has solved in this stage.
  int iteration() const { return iteration_; }
  bool initialised() const { return initialised_; }
  // ||x_solve - x_old||_2 over the robot's stacked unknowns at its last solve (9 numbers per
  // variable in stage 1, 6 in stage 2); +infinity before the first solve of a stage.
  double lastChange() const { return last_change_; }

  // The current estimate of the robot's variables: initial values (kIdle), projected rotations
  // with zero translation (kRotation), R_hat Exp(dtheta), t (kPose, kDone). The anchor is always
  // its initial value.
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
  };
  struct StageInbox {
    std::map<Key, Eigen::VectorXd> values;
    std::map<int, std::int64_t> last_iteration;
    std::set<int> initialised_robots;
  };

  DgsStage currentStage() const;
  void prepareStage(DgsStage stage);
  StageInbox& inbox(DgsStage stage);
  bool usable(const Separator& s, DgsStage stage) const;
  Eigen::MatrixXd neighbourValue(const Key& key, DgsStage stage) const;

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
  std::vector<Eigen::VectorXd> x_;              // per unknown, StageDimension of the stage
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
  std::unique_ptr<BlockLeastSquares> rotation_problem_, pose_problem_;
  std::int64_t duplicates_ = 0, stale_ = 0;
};

}  // namespace moslam
