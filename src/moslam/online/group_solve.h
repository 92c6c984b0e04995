// Online mapping at a rendezvous: the joint graph of the robots in range, and its solution
// handed back to each robot (issue 13; online_team.h runs it in one process).
//
// Each robot keeps its own SLAM in its own frame (first pose at the identity, object_slam.h).
// At a rendezvous the robots in range solve the joint graph of their maps: their own graphs,
// one object-object factor per shared pair between two of them, and for every shared pair with
// a robot out of range a *team factor*: the partner's landmark held fixed at its last received
// estimate. A robot holds that estimate in its own frame, y = x_{r,0}^-1 o_c (x_{r,0} its first
// pose, o_c the partner landmark, both from the same solve), so the factor is between the
// robot's first pose and its landmark (HeldFactor) and the joint graph has relative factors only:
// its cost does not change under a rigid motion of the whole group, and holding the lowest robot's
// first pose (the solve's gauge, after re-labelling the group's robots 0..k-1) constrains
// nothing. After the solve each robot takes its variables back into its own frame
// (x_{r,0}^-1 x) and holds the landmarks of its partners in range the same way.
// Several robots of a group may hold copies of the same partner robot's landmarks, received at
// different meetings. The group takes each partner robot's landmarks from the robot of the group
// that met it last (the latest solve; ties: the pair's own robot, then the lowest id), where that
// robot holds them, as factors between its first pose and each paired landmark (GroupTeamFactors).
// So a stale copy (from before a later solve of another robot with that partner) does not pull
// against a fresh one, and the partner's landmarks are, where possible, one rigid set in one frame
// as in the joint graph. With the robots out of range held at the joint optimum by one holder
// each, the group's optimum is the joint optimum (test WithThePartnerHeldAtTheJointOptimum...);
// landmarks that only another robot holds are anchored at that robot's frame, which breaks this.
#pragma once

#include <map>
#include <set>
#include <vector>

#include "moslam/graph/pose_graph.h"
#include "moslam/slam/object_slam.h"
#include "moslam/slam/rendezvous.h"

namespace moslam {

// A partner landmark a robot holds: its estimate in the holder's own frame, and the time step of
// the group solve that gave it.
struct HeldEstimate {
  SE3 pose;
  int step = 0;
};
// The partner landmarks a robot holds, by the partner landmark's key.
using HeldEstimates = std::map<Key, HeldEstimate>;

// A shared pair of a group robot's landmark `mine` with `other`, a landmark of a robot outside the
// group, and that robot's copy of `other` if it holds one (what it tells the group when it
// joins: transport/robot_session.h).
struct TeamPair {
  Key mine;
  Key other;
  bool mine_is_alpha = false;  // the pair's direction (SharedObject): the factor's sign convention
  bool held = false;           // mine's robot holds a copy of `other`:
  HeldEstimate copy;
};

// The factor between Key::Pose(holder, 0) and robot's landmark that has the cost of `shared` (an
// object-object factor with one end robot's landmark) with the partner landmark at
// x_{holder,0} * held, whatever x_{holder,0}; holder < 0: the robot itself. Throws
// InvalidInputError when `shared` has no end, or two ends, of `robot`.
RelativePoseFactor HeldFactor(const RelativePoseFactor& shared, int robot, const SE3& held,
                              int holder = -1);

// The pairs of `robot` with landmarks of robots not in `group` (in the order of `shared`), with
// its copies from `held`.
std::vector<TeamPair> RobotTeamPairs(int robot, const std::vector<SharedObject>& shared,
                                     const HeldEstimates& held, const std::set<int>& group);

// The team factors of a group from its robots' team pairs (each robot's RobotTeamPairs, in any
// order): for each pair (mine, other) whose `other` some robot of the group holds, HeldFactor with
// the copy of `other` of the holder that met other's robot last (the largest step among its
// copies of that robot's landmarks; ties: mine's robot, then the lowest robot), anchored at the
// holder's first pose. Sorted by (mine, other); `holders` (optional) receives the holder of each
// factor. Throws InvalidInputError on a pair twice, or a pair whose ends are of one robot.
std::vector<RelativePoseFactor> GroupTeamFactors(const std::vector<TeamPair>& pairs,
                                                 const Matrix6& lambda,
                                                 std::vector<int>* holders = nullptr);

// The team factors of `robot` for its own SLAM between rendezvous: HeldFactor of each shared pair of the robot whose partner is not
// in `in_range` and whose partner landmark it holds (pairs found but never solved together have
// none yet).
std::vector<RelativePoseFactor> TeamFactors(int robot, const std::vector<SharedObject>& shared,
                                            const HeldEstimates& held, const Matrix6& lambda,
                                            const std::set<int>& in_range = {});

// The robots of `robots` linked through shared pairs between two of them, each group sorted,
// groups by their lowest robot; a robot with no such pair is a group of one.
std::vector<std::vector<int>> LinkedGroups(const std::vector<int>& robots,
                                           const std::vector<SharedObject>& shared);

struct GroupProblem {
  std::vector<int> robots;  // increasing ids: robot i of the solve is robots[i]
  PoseGraph graph;          // keys re-labelled robots[i] -> i; the gauge is robots[0]'s first pose
  Values initial;           // each robot's own estimate (its own frame), re-labelled
  int object_object = 0;    // shared pairs between robots of the group
  int team_factors = 0;     // shared pairs with robots out of range, as held factors
  int borrowed = 0;         // team factors with the copy of another robot of the group
  std::vector<bool> team;   // per factor of graph: whether it is a team (held) factor
  // Per robot of the group (in `robots` order): the index in graph of the first factor of its
  // own graph (ObjectSlam::graph(), whose factors follow in their order).
  std::vector<std::size_t> own_first;
};

// The joint graph of `group` (2 or more distinct robots, linked: LinkedGroups) with the pairs of
// `shared` and each robot's held estimates (`held`, by robot id; a robot may have none).
// Throws InvalidInputError on fewer than two robots, a repeated robot, or robots not linked.
GroupProblem BuildGroupProblem(const std::vector<const ObjectSlam*>& group,
                               const std::vector<SharedObject>& shared,
                               const std::map<int, HeldEstimates>& held, const Matrix6& lambda);

// One robot's part of the group problem, for a solve in which each robot holds only its own
// part (the robot processes, transport/robot_session.h): the factors of BuildGroupProblem that
// touch its variables, in the same order (per robot of the group: its own graph, then its team
// factors; then the shared pairs with the group's robots in the order of `shared`), and its own
// estimate, re-labelled. `robots`: the group (increasing ids, 2 or more, this robot among them;
// LinkedGroups); `team`: the team pairs of every robot of the group (RobotTeamPairs). Throws
// InvalidInputError otherwise.
struct RobotGroupPart {
  int local = 0;          // the robot's id in the solve (its index in `robots`)
  PoseGraph subgraph;     // re-labelled keys
  Values initial;         // its own estimate (its own frame), re-labelled
  int object_object = 0;  // shared pairs with robots of the group
  int team_factors = 0;   // its team factors (on its landmarks)
  std::vector<bool> team;      // per factor of subgraph: a team (held) factor, its own or one
                               // anchored at its first pose (GroupProblem::team alike)
  std::size_t own_first = 0;   // the index in subgraph of the first factor of its own graph
};
RobotGroupPart BuildRobotGroupPart(const ObjectSlam& robot, const std::vector<int>& robots,
                                   const std::vector<SharedObject>& shared,
                                   const std::vector<TeamPair>& team, const Matrix6& lambda);

// What one robot of the group takes from a solution of the problem.
struct GroupUpdate {
  int robot = 0;
  Values estimate;      // its variables, in its own frame (first pose the identity)
  HeldEstimates held;   // the landmarks of its partners in the group, in its own frame, at `step`
};

// Per robot of the problem (in its order), held copies stamped `step`. `solution`: re-labelled
// keys, every variable of the problem. Throws InvalidInputError when a variable is missing.
std::vector<GroupUpdate> SplitGroupSolution(const GroupProblem& problem, const Values& solution,
                                            const std::vector<SharedObject>& shared, int step);

// The update of `robot` (one of `robots`, the group as in BuildRobotGroupPart) from `solution`
// (re-labelled keys): every variable of that robot it holds and the landmarks of its partners in
// the group (a robot process: its own estimate and its copies of its neighbours' variables).
// `left`: robots of the group that left during the solve (transport/dgs_node.h): the solution
// holds their variables only when they sent some before they left; a landmark of theirs it lacks
// is not taken (the robot keeps the copy it held before). Throws InvalidInputError when its first
// pose or the landmark of a partner that did not leave is missing.
GroupUpdate RobotGroupUpdate(const std::vector<int>& robots, int robot, const Values& solution,
                             const std::vector<SharedObject>& shared, int step,
                             const std::set<int>& left = {});

}  // namespace moslam
