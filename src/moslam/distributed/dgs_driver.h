// In-process driver of the distributed Gauss-Seidel solver (shared/DGS.md): N robot agents
// (robot_agent.h), one per robot owning variables (partition.h), run stage 1 (rotations) then
// stage 2 (pose step). Every message that crosses between agents is serialized
// (messages.h), counted, and the DECODED bytes are delivered, so message and byte counts are the
// real traffic.
//
//   DgsResult r = RunDgs(graph, initial, options);
//
// Per stage: every agent starts the stage; without flagged initialisation the agents first
// exchange their initial estimates (iteration 0 messages, counted in iteration 0). Then sweeps:
// each robot, in the robot order, solves once; Gauss-Seidel delivers its messages before the
// next robot solves, Jacobi delivers all messages at the end of the sweep. The stage stops after
// the first sweep in which every live robot has solved in the stage and changed by at most eta
// (lastChange() <= eta), or after max_iterations sweeps. A robot that cannot solve yet (flagged
// initialisation) sends nothing that sweep. The sweeps converge linearly, so the distance left to
// the fixed point (the centralized two-stage estimate) is about eta * rho / (1 - rho) for a
// per-sweep contraction rho; on blocks_world rho reaches 0.97 in stage 1 and 0.9996 in stage 2.
//
// Robot order: robot 0 first; with flagged initialisation, then repeatedly every robot not yet
// ordered that is linked to the ordered set, most linking neighbour variables first (ties: lower
// robot id), then any robot left over; without it, 0, 1, ..., N-1.
//
// Faults (FaultInjection): a robot that stops answering stops at the start of a given sweep: it
// no longer solves, sends or receives; the others keep its last estimate, finish, and the result
// lists it (its variables keep the estimate it had). Messages can be duplicated, replayed stale
// (the previous sweep's messages re-delivered after the current ones) and shuffled within each
// delivery batch; the agents ignore duplicates and stale messages, so the estimate is unchanged.
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "moslam/distributed/dgs_types.h"
#include "moslam/graph/pose_graph.h"

namespace moslam {

struct DgsOptions {
  double eta_rotation = 1e-2;  // stage 1 stops when every robot's change is <= this
  double eta_pose = 1e-2;      // stage 2 likewise
  double gamma = 1.0;          // over-relaxation in (0, 2); 1: plain Gauss-Seidel / Jacobi
  SweepOrder order = SweepOrder::kGaussSeidel;
  int max_iterations = 1000;   // sweeps per stage
  bool flagged_initialisation = true;
  bool weight_by_information = false;  // unit weights as the DGS reference

  // Throws InvalidInputError naming the first bad field.
  void validate() const;
};

struct SilentRobot {
  int robot = 0;
  DgsStage stage = DgsStage::kRotation;
  int iteration = 1;  // stops answering at the start of this sweep (1-based) of `stage`
};

struct FaultInjection {
  std::vector<SilentRobot> silent;
  bool duplicate = false;     // deliver every message twice
  bool replay_stale = false;  // re-deliver the previous sweep's messages after the current ones
  bool shuffle = false;       // deliver each batch in a random order
  std::uint32_t seed = 1;     // for shuffle
};

enum class StageStatus { kNotRun, kConverged, kMaxIterations };
std::string ToString(StageStatus status);

struct DgsIterationStats {
  DgsStage stage = DgsStage::kRotation;
  int iteration = 0;          // 0: the initial exchange (no flagged initialisation)
  std::int64_t messages = 0;  // serialized messages sent during this sweep
  std::int64_t bytes = 0;
  double max_change = 0.0;    // over the live robots (+inf while one has not solved yet)
  int robots_solved = 0;
  double seconds = 0.0;
};

struct DgsStageReport {
  StageStatus status = StageStatus::kNotRun;
  int iterations = 0;  // sweeps
  std::int64_t messages = 0;
  std::int64_t bytes = 0;
  double final_change = 0.0;
};

struct SilentRobotReport {
  int robot = 0;
  DgsStage stage = DgsStage::kRotation;
  int iteration = 0;  // the sweep at whose start it stopped answering (0: before the stage)
};

struct DgsResult {
  Values values;  // every variable: the live robots' final estimates, the silent robots' last
  DgsStageReport rotation, pose;
  std::vector<DgsIterationStats> history;
  std::int64_t messages = 0;
  std::int64_t bytes = 0;
  std::vector<int> order;                   // the robot order used
  std::vector<SilentRobotReport> silent;    // robots that stopped answering
  std::int64_t duplicates_ignored = 0;      // summed over agents
  std::int64_t stale_ignored = 0;
  double seconds = 0.0;
};

class RobotAgent;

// The driver as a class, so further stages (distributed refinement) can be run on the same
// agents: construct, runRotationStage(), runPoseStage(), result().
class DgsDriver {
 public:
  // Partitions `graph` by the robot in each key and builds one agent per robot owning
  // variables. Variables missing from `initial` start at the identity (the anchor included).
  // Throws InvalidInputError (bad options, a silent robot that does not exist),
  // UnderdeterminedError (robot 0 has no pose, part of the graph not connected to the anchor).
  DgsDriver(const PoseGraph& graph, const Values& initial, const DgsOptions& options = {},
            const FaultInjection& faults = {});
  ~DgsDriver();
  DgsDriver(const DgsDriver&) = delete;
  DgsDriver& operator=(const DgsDriver&) = delete;

  const DgsStageReport& runRotationStage();  // must be first
  const DgsStageReport& runPoseStage();      // after runRotationStage(); finishes the agents
  // The result so far (values: every agent's current estimate).
  DgsResult result() const;

  const std::vector<int>& order() const { return order_; }
  int numAgents() const { return static_cast<int>(agents_.size()); }
  // The agent of `robot` (InvalidInputError when no agent owns variables of that robot).
  RobotAgent& agent(int robot);

 private:
  struct Wire {
    int from = 0;
    int to = 0;
    std::vector<std::uint8_t> bytes;
  };
  void runStage(DgsStage stage, DgsStageReport& report);
  void updateSilence(DgsStage stage, int iteration);
  void transmit(std::vector<Wire> batch, DgsIterationStats& stats);
  std::vector<Wire> encodeOutgoing(int robot) const;
  bool live(int robot) const;

  DgsOptions options_;
  FaultInjection faults_;
  std::map<int, std::unique_ptr<RobotAgent>> agents_;
  std::vector<int> order_;
  std::map<int, SilentRobotReport> silent_;
  std::map<int, std::vector<Wire>> previous_;  // per sender: its previous sweep's messages
  std::uint64_t rng_state_ = 1;
  DgsResult result_;
};

// Partitions `graph` by the robot in each key and runs both stages. Variables missing from
// `initial` start at the identity (the anchor included). Throws InvalidInputError (bad options,
// a silent robot that does not exist), UnderdeterminedError (robot 0 has no pose, a part of the
// graph is not connected to the anchor).
DgsResult RunDgs(const PoseGraph& graph, const Values& initial, const DgsOptions& options = {},
                 const FaultInjection& faults = {});

// The robot order described above, from links[i] = {robot j: number of neighbour variables of
// robot i owned by j} for the robots `robots` (ascending; robot 0 first if present).
std::vector<int> FlaggedRobotOrder(const std::vector<int>& robots,
                                   const std::vector<std::map<int, int>>& links);

}  // namespace moslam
