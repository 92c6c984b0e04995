// Online mapping in one process: the robots solve at every rendezvous (group_solve.h) with the
// distributed solver (distributed/dgs_driver.h: two-level DGS, then the refinement to the
// group's optimum), as the robot processes do over the network with the same robot program.
//
//   OnlineTeam team(options);
//   MultiRobotSlamConfig slam = ...;
//   slam.on_rendezvous = team.hook();
//   RunMultiRobotObjectSlam(data, slam);   // the robots' maps are updated at every rendezvous
//
// At a group of robots in range (RendezvousGroup) the team splits it into the robots linked by
// shared objects among them (LinkedGroups, without the robots that have left: RendezvousGroup::
// gone; a robot linked to none only refreshes its own graph), solves each part of two or more robots, hands every robot its estimate in its own
// frame, the landmarks of its partners in range, and its team factors for the shared pairs with
// every partner (so its own SLAM keeps what the team told it until the next rendezvous).
//
// Robust (OnlineOptions::robust): a group solves with RunRobustDgs (distributed/robust_dgs.h:
// the separator check, then GNC-TLS by the robots), as `simulate --robust` solves the batch: the
// shared pairs among its robots and the object-pose factors of their own graphs robust, the
// check testing the pairs in the robots' own maps (without the held factors). Every solve of a
// group judges all its robots' pairs and object-pose factors again (GNC-TLS from least squares),
// and its verdicts stand until the next solve that judges them:
//   - a pair rejected is *set aside*: it stays in the team's list (so its two robots judge it
//     again when they meet) but gives no factor anywhere else: no held factor in a robot's own
//     SLAM, no team factor in a group without both its robots, not in the team's final map
//     (AcceptedPairs);
//   - an object-pose factor rejected keeps GNC's min_weight in the robot's own SLAM
//     (ObjectSlam::setFactorWeights) until the robot's next group solve.
// The held (team) factors are pairs that a group with both of their robots accepted; they stay
// least squares. The robot processes run the same solves (transport/robot_session.h with
// dgs.gnc: RobustGroupFactors on each robot's part, JudgePairs on each robot's own pairs).
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <set>
#include <utility>
#include <vector>

#include "moslam/distributed/dgs_driver.h"
#include "moslam/distributed/robust_dgs.h"
#include "moslam/online/group_solve.h"
#include "moslam/sim/sensing.h"
#include "moslam/slam/multi_robot.h"

namespace moslam {

struct OnlineOptions {
  // The solver of a group: as `moslam robot --online` runs it (the robot program's Jacobi
  // order, two-level, error-bound rule, refinement).
  DgsOptions solver = DefaultSolver();
  Matrix6 lambda = RendezvousConfig().lambda();  // object-object information
  // Fault experiments (robot id -> step): the robot takes part in the rendezvous of that step and
  // in no group solve from then on, as a robot process that dies after its joining status and
  // before its first step of the solve (transport/robot_session.h: its partners form the group
  // again without it, its pairs with them held). Give it MultiRobotSlamConfig::leave_after the
  // same step, so that it takes part in nothing later.
  std::map<int, int> dies_in_solve;
  // Outlier-robust group solves (see the top): RunRobustDgs with these options, their `dgs`
  // replaced by `solver`. A group in which the separator check leaves some robot with no pair it
  // accepts (RunRobustDgs throws UnderdeterminedError: a robot pair with too few agreeing pairs
  // to confirm itself, e.g. two pairs at a first meeting) is not solved: the maps stay as they
  // are and the pairs wait for the next meeting (GroupSolveRecord::unlinked). Not set: least
  // squares.
  std::optional<RobustDgsOptions> robust;
  // Throws InvalidInputError naming the first bad field.
  void validate() const;
  static DgsOptions DefaultSolver();
};

struct GroupSolveRecord {
  int step = 0;
  std::vector<int> robots;  // the solved part of the group in range
  int object_object = 0;    // shared pairs among them
  int team_factors = 0;     // held factors (pairs with robots out of range)
  int borrowed = 0;         // of them, with the copy of another robot of the group
  int rotation_sweeps = 0, pose_sweeps = 0, refine_steps = 0;
  StageStatus refine_status = StageStatus::kNotRun;
  double initial_cost = 0.0;  // F of the group graph at the robots' own estimates
  double final_cost = 0.0;
  std::int64_t messages = 0, bytes = 0;  // the solve's traffic (distributed/messages.h)
  double seconds = 0.0;
  // Robust solves (OnlineOptions::robust; then messages and the per-stage counts above are 0,
  // bytes are all of the robust solve's: RobustDgsResult::bytes()).
  bool unlinked = false;   // the check left a robot unlinked: not solved, nothing changed
  int robust_rounds = 0;   // GNC's weighted solves after the least-squares one
  int sweeps = 0;          // all stages of all its solves
  int rejected = 0;        // pairs among the group's robots set aside by this solve
  int taken_back = 0;      // ... pairs set aside before that this solve accepts
  int observation_outliers = 0;  // object-pose factors of the robots' own graphs it rejects
  std::int64_t robust_extra_bytes = 0;  // weights, GNC's control, the check's messages
};

// The pairs of `shared` that are not set aside (in `set_aside`, either direction), in order.
std::vector<SharedObject> AcceptedPairs(const std::vector<SharedObject>& shared,
                                        const std::vector<SharedObject>& set_aside);

// Two landmarks as an unordered pair: either direction of a shared pair.
std::pair<Key, Key> UnorderedPair(const Key& a, const Key& b);

// The masks of a robust group solve over a group's graph (GroupProblem::graph with its team
// flags, or a robot's RobotGroupPart::subgraph with its own): robust, ObjectFactors (gnc.h: the
// shared pairs between two robots, the object-pose factors of the robots' own graphs and their
// loop-closure pairs) but the team factors (pose-object factors too, not robust); checked (the
// separator check's), every factor but the team ones.
struct RobustGroupMasks {
  std::vector<bool> robust, checked;
};
RobustGroupMasks RobustGroupFactors(const PoseGraph& graph, const std::vector<bool>& team);

// The shared pairs a robust group solve judged: the object-object factors between two robots of
// `graph` (robot i of the solve is robots[i]), as UnorderedPair of the robots' own keys, and of
// them those whose weight (one per factor) is below 0.5.
struct JudgedPairs {
  std::set<std::pair<Key, Key>> judged, rejected;
};
JudgedPairs PairsJudged(const PoseGraph& graph, const std::vector<double>& weights,
                        const std::vector<int>& robots);

// A robust group solve's verdicts on a robot's own factors: the indices j in [0, count) whose
// factor, at `first + j` of the solve's graph, has a weight below 0.5 (as PairsJudged). Throws
// InvalidInputError when `weights` ends before first + count.
std::vector<std::uint32_t> RejectedOwnFactors(const std::vector<double>& weights,
                                              std::size_t first, std::size_t count);

// A robust group solve's verdicts on shared pairs (UnorderedPair, real ids): of `set_aside`, the
// pairs it did not judge or rejected again stay (the others are taken back), then every pair of
// `shared` it rejected and that was not set aside is set aside, in the order of `shared`.
struct PairVerdicts {
  std::vector<SharedObject> set_aside;
  int rejected = 0;    // pairs newly set aside
  int taken_back = 0;  // pairs set aside before that it accepts
};
PairVerdicts JudgePairs(const std::vector<SharedObject>& shared,
                        const std::vector<SharedObject>& set_aside,
                        const std::set<std::pair<Key, Key>>& judged,
                        const std::set<std::pair<Key, Key>>& rejected);

class OnlineTeam {
 public:
  // Throws InvalidInputError on bad options.
  explicit OnlineTeam(OnlineOptions options = {});

  // Solves `group` (see the top) and updates the robots of `team`. Throws what the solver
  // throws; a robot's map is replaced only after its part was solved.
  void onRendezvous(const RendezvousGroup& group, MultiRobotSlamResult& team);
  // onRendezvous bound to this object, then `after` (may be null) with the records of this
  // group's solves; this object must outlive the hook.
  MultiRobotSlamConfig::OnRendezvous hook(
      std::function<void(const RendezvousGroup&, const MultiRobotSlamResult&)> after = {});

  const std::vector<GroupSolveRecord>& solves() const { return solves_; }
  // The partner landmarks each robot holds (robot id -> held estimates).
  const std::map<int, HeldEstimates>& held() const { return held_; }
  // Robust: the pairs set aside now (the last solve that judged each rejected it, and still in
  // the team's list at the last rendezvous), in the order they were set aside. Least squares:
  // none.
  const std::vector<SharedObject>& setAside() const { return set_aside_; }

 private:
  // Solves one linked part of a group (2 or more robots) and updates its robots.
  void solvePart(const std::vector<int>& part, int step, MultiRobotSlamResult& team);
  // The pairs the group solves with: every pair among its robots (judged again when robust), and
  // the accepted pairs with the robots out of range (as held factors).
  std::vector<SharedObject> pairsFor(const std::vector<int>& part,
                                     const MultiRobotSlamResult& team) const;
  Values solveLeastSquares(const GroupProblem& problem, GroupSolveRecord& rec) const;
  // Judges the group's pairs and its robots' own factors; nullopt when the separator check left
  // some robot of the group unlinked (nothing judged).
  std::optional<Values> solveRobust(const GroupProblem& problem, const std::vector<int>& part,
                                    MultiRobotSlamResult& team, GroupSolveRecord& rec);
  // The solution into the group's robots: their maps, held copies and team factors.
  void applySolution(const GroupProblem& problem, const Values& solution, int step,
                     MultiRobotSlamResult& team);

  OnlineOptions options_;
  std::vector<GroupSolveRecord> solves_;
  std::map<int, HeldEstimates> held_;
  std::vector<SharedObject> set_aside_;
};

// A whole online run in one process: RunMultiRobotObjectSlam(data, slam) with an OnlineTeam of
// `options` at every rendezvous, and each robot's map right after every solve it took part in
// (what the robot processes save, transport/robot_session.h).
struct OnlineRun {
  MultiRobotSlamResult slam;             // the maps at the end
  std::vector<GroupSolveRecord> solves;  // in order
  std::map<std::pair<int, int>, Values> maps;  // (step, robot) -> its map after that solve
  std::vector<SharedObject> set_aside;   // robust: the pairs set aside at the end
};
OnlineRun RunOnline(const SimulationData& data, MultiRobotSlamConfig slam, OnlineOptions options);

}  // namespace moslam
