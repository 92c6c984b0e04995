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
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <utility>
#include <vector>

#include "moslam/distributed/dgs_driver.h"
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
};

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

 private:
  OnlineOptions options_;
  std::vector<GroupSolveRecord> solves_;
  std::map<int, HeldEstimates> held_;
};

// A whole online run in one process: RunMultiRobotObjectSlam(data, slam) with an OnlineTeam of
// `options` at every rendezvous, and each robot's map right after every solve it took part in
// (what the robot processes save, transport/robot_session.h).
struct OnlineRun {
  MultiRobotSlamResult slam;             // the maps at the end
  std::vector<GroupSolveRecord> solves;  // in order
  std::map<std::pair<int, int>, Values> maps;  // (step, robot) -> its map after that solve
};
OnlineRun RunOnline(const SimulationData& data, MultiRobotSlamConfig slam, OnlineOptions options);

}  // namespace moslam
