#include "moslam/online/group_solve.h"

#include <algorithm>
#include <functional>
#include <set>
#include <string>
#include <tuple>

#include "moslam/common/errors.h"
#include "moslam/graph/robot_groups.h"
#include "moslam/slam/multi_robot.h"

namespace moslam {
namespace {

Key Relabel(Key k, int robot) {
  k.robot = robot;
  return k;
}

// The index of `robot` in `robots` (increasing, distinct, 2 or more), the robot's id in the solve.
int LocalIndex(const std::vector<int>& robots, int robot, const char* who) {
  if (robots.size() < 2 || std::adjacent_find(robots.begin(), robots.end(),
                                              std::greater_equal<int>()) != robots.end()) {
    throw InvalidInputError(std::string(who) +
                            ": a group is two or more distinct robots in increasing order");
  }
  const auto it = std::lower_bound(robots.begin(), robots.end(), robot);
  if (it == robots.end() || *it != robot) {
    throw InvalidInputError(std::string(who) + ": robot " + std::to_string(robot) +
                            " is not in the group");
  }
  return static_cast<int>(it - robots.begin());
}

// The object-object factor of a team pair, in the direction of its shared pair.
RelativePoseFactor PairFactor(const TeamPair& t, const Matrix6& lambda) {
  return ObjectObjectFactor(t.mine_is_alpha ? SharedObject{t.other, t.mine}
                                            : SharedObject{t.mine, t.other},
                            lambda);
}

}  // namespace

RelativePoseFactor HeldFactor(const RelativePoseFactor& shared, int robot, const SE3& held,
                              int holder) {
  const bool owns_a = shared.a().robot == robot, owns_b = shared.b().robot == robot;
  if (owns_a == owns_b) {
    throw InvalidInputError("HeldFactor: the factor between " + ToString(shared.a()) + " and " +
                            ToString(shared.b()) + " does not join robot " +
                            std::to_string(robot) + " to another robot");
  }
  const Key first = Key::Pose(holder < 0 ? robot : holder, 0);
  const SE3& z = shared.measured();
  if (owns_b) {
    // Log(z^-1 (x0 y)^-1 b) = Log((y z)^-1 x0^-1 b).
    return RelativePoseFactor(first, shared.b(), held * z, shared.information());
  }
  // Log(z^-1 a^-1 x0 y) = -Ad(z^-1) Log((y z^-1)^-1 x0^-1 a): the same cost with the
  // information seen through Ad(z^-1).
  const Matrix6 ad = z.inverse().Adjoint();
  const Matrix6 info = ad.transpose() * shared.information() * ad;
  return RelativePoseFactor(first, shared.a(), held * z.inverse(), 0.5 * (info + info.transpose()));
}

std::vector<TeamPair> RobotTeamPairs(int robot, const std::vector<SharedObject>& shared,
                                     const HeldEstimates& held, const std::set<int>& group) {
  std::vector<TeamPair> out;
  for (const auto& s : shared) {
    const Key mine = s.alpha_object.robot == robot ? s.alpha_object : s.beta_object;
    const Key other = s.alpha_object.robot == robot ? s.beta_object : s.alpha_object;
    if (mine.robot != robot || other.robot == robot || group.count(other.robot) > 0) continue;
    TeamPair t{mine, other, mine == s.alpha_object, false, {}};
    const auto it = held.find(other);
    if (it != held.end()) {
      t.held = true;
      t.copy = it->second;
    }
    out.push_back(t);
  }
  return out;
}

std::vector<RelativePoseFactor> GroupTeamFactors(const std::vector<TeamPair>& pairs,
                                                 const Matrix6& lambda,
                                                 std::vector<int>* holders) {
  std::vector<TeamPair> sorted = pairs;
  std::sort(sorted.begin(), sorted.end(), [](const TeamPair& a, const TeamPair& b) {
    return a.mine < b.mine || (a.mine == b.mine && a.other < b.other);
  });
  std::map<Key, std::map<int, HeldEstimate>> copies;  // partner landmark -> holder -> copy
  std::map<std::pair<int, int>, int> freshest;        // (partner robot, holder) -> latest step
  for (std::size_t i = 0; i < sorted.size(); ++i) {
    const TeamPair& t = sorted[i];
    if (t.mine.robot == t.other.robot) {
      throw InvalidInputError("GroupTeamFactors: the pair " + ToString(t.mine) + " - " +
                              ToString(t.other) + " does not join two robots");
    }
    if (i > 0 && sorted[i - 1].mine == t.mine && sorted[i - 1].other == t.other) {
      throw InvalidInputError("GroupTeamFactors: the pair " + ToString(t.mine) + " - " +
                              ToString(t.other) + " twice");
    }
    if (!t.held) continue;
    copies[t.other][t.mine.robot] = t.copy;
    int& f = freshest[{t.other.robot, t.mine.robot}];
    f = std::max(f, t.copy.step);
  }
  std::vector<RelativePoseFactor> out;
  if (holders != nullptr) holders->clear();
  for (const TeamPair& t : sorted) {
    const auto it = copies.find(t.other);
    if (it == copies.end()) continue;
    // The holder that met the partner robot last; ties: the pair's own robot, then the lowest.
    const auto rank = [&](int h) {
      return std::make_tuple(freshest.at({t.other.robot, h}), h == t.mine.robot, -h);
    };
    auto best = it->second.begin();
    for (auto c = it->second.begin(); c != it->second.end(); ++c) {
      if (rank(c->first) > rank(best->first)) best = c;
    }
    out.push_back(HeldFactor(PairFactor(t, lambda), t.mine.robot, best->second.pose, best->first));
    if (holders != nullptr) holders->push_back(best->first);
  }
  return out;
}

std::vector<RelativePoseFactor> TeamFactors(int robot, const std::vector<SharedObject>& shared,
                                            const HeldEstimates& held, const Matrix6& lambda,
                                            const std::set<int>& in_range) {
  std::vector<RelativePoseFactor> out;
  for (const TeamPair& t : RobotTeamPairs(robot, shared, held, in_range)) {
    if (t.held) out.push_back(HeldFactor(PairFactor(t, lambda), robot, t.copy.pose));
  }
  return out;
}

std::vector<std::vector<int>> LinkedGroups(const std::vector<int>& robots,
                                           const std::vector<SharedObject>& shared) {
  std::vector<std::pair<int, int>> links;
  for (const auto& s : shared) links.emplace_back(s.alpha_object.robot, s.beta_object.robot);
  return ConnectedRobots(robots, links);
}

GroupProblem BuildGroupProblem(const std::vector<const ObjectSlam*>& group,
                               const std::vector<SharedObject>& shared,
                               const std::map<int, HeldEstimates>& held, const Matrix6& lambda) {
  GroupProblem p;
  for (const ObjectSlam* robot : group) {
    if (robot == nullptr) throw InvalidInputError("BuildGroupProblem: a null robot");
    p.robots.push_back(robot->robot());
  }
  std::vector<const ObjectSlam*> ordered = group;
  std::sort(ordered.begin(), ordered.end(),
            [](const ObjectSlam* a, const ObjectSlam* b) { return a->robot() < b->robot(); });
  std::sort(p.robots.begin(), p.robots.end());
  if (p.robots.size() < 2 ||
      std::adjacent_find(p.robots.begin(), p.robots.end()) != p.robots.end()) {
    throw InvalidInputError("BuildGroupProblem: a group is two or more distinct robots");
  }
  if (LinkedGroups(p.robots, shared).size() != 1) {
    throw InvalidInputError(
        "BuildGroupProblem: the robots are not linked by shared objects among them (split them "
        "with LinkedGroups first)");
  }
  std::map<int, int> label;
  for (std::size_t i = 0; i < p.robots.size(); ++i) label[p.robots[i]] = static_cast<int>(i);
  const std::set<int> in_range(p.robots.begin(), p.robots.end());
  const auto relabel = [&](Key k) { return Relabel(k, label.at(k.robot)); };
  const auto add = [&](const RelativePoseFactor& f, bool team_factor = false) {
    p.graph.add(RelativePoseFactor(relabel(f.a()), relabel(f.b()), f.measured(),
                                   f.information()));
    p.team.push_back(team_factor);
  };
  std::vector<TeamPair> team;
  for (const ObjectSlam* robot : ordered) {
    const auto h = held.find(robot->robot());
    const auto pairs = RobotTeamPairs(robot->robot(), shared,
                                      h != held.end() ? h->second : HeldEstimates{}, in_range);
    team.insert(team.end(), pairs.begin(), pairs.end());
  }
  std::vector<int> holders;
  const std::vector<RelativePoseFactor> team_factors = GroupTeamFactors(team, lambda, &holders);
  std::size_t next = 0;  // sorted by their landmark: robot by robot
  for (const ObjectSlam* robot : ordered) {
    const PoseGraph own = robot->graph();
    p.own_first.push_back(p.graph.factors().size());
    for (const auto& f : own.factors()) add(f);
    for (; next < team_factors.size() && team_factors[next].b().robot == robot->robot(); ++next) {
      add(team_factors[next], true);
      ++p.team_factors;
      if (holders[next] != robot->robot()) ++p.borrowed;
    }
    for (const auto& [k, x] : robot->estimate()) p.initial.emplace(relabel(k), x);
  }
  for (const auto& s : shared) {
    if (in_range.count(s.alpha_object.robot) == 0 || in_range.count(s.beta_object.robot) == 0 ||
        s.alpha_object.robot == s.beta_object.robot) {
      continue;
    }
    add(ObjectObjectFactor(s, lambda));
    ++p.object_object;
  }
  return p;
}

std::vector<GroupUpdate> SplitGroupSolution(const GroupProblem& problem, const Values& solution,
                                            const std::vector<SharedObject>& shared, int step) {
  for (const auto& [k, x] : problem.initial) {
    if (solution.count(k) == 0) {
      throw InvalidInputError("SplitGroupSolution: the solution has no value for " + ToString(k));
    }
  }
  std::vector<GroupUpdate> out;
  for (int r : problem.robots) {
    out.push_back(RobotGroupUpdate(problem.robots, r, solution, shared, step));
  }
  return out;
}

RobotGroupPart BuildRobotGroupPart(const ObjectSlam& robot, const std::vector<int>& robots,
                                   const std::vector<SharedObject>& shared,
                                   const std::vector<TeamPair>& team, const Matrix6& lambda) {
  const int self = robot.robot();
  const int local = LocalIndex(robots, self, "BuildRobotGroupPart");
  RobotGroupPart part;
  part.local = local;
  const std::set<int> in_range(robots.begin(), robots.end());
  const auto relabel = [&](Key k) {
    return Relabel(k, LocalIndex(robots, k.robot, "BuildRobotGroupPart"));
  };
  const auto add = [&](const RelativePoseFactor& f, bool team_factor) {
    part.subgraph.add(RelativePoseFactor(relabel(f.a()), relabel(f.b()), f.measured(),
                                         f.information()));
    part.team.push_back(team_factor);
  };
  for (const TeamPair& t : team) {
    if (in_range.count(t.mine.robot) == 0 || in_range.count(t.other.robot) > 0) {
      throw InvalidInputError("BuildRobotGroupPart: the team pair " + ToString(t.mine) + " - " +
                              ToString(t.other) +
                              " is not one of a robot of the group with a robot outside it");
    }
  }
  // BuildGroupProblem's order, restricted to the factors on this robot's variables: per robot of
  // the group its own graph and its team factors (those anchored at this robot's first pose).
  const std::vector<RelativePoseFactor> team_factors = GroupTeamFactors(team, lambda);
  std::size_t next = 0;
  for (int r : robots) {
    if (r == self) {
      const PoseGraph own = robot.graph();
      part.own_first = part.team.size();
      for (const auto& f : own.factors()) add(f, false);
    }
    for (; next < team_factors.size() && team_factors[next].b().robot == r; ++next) {
      const RelativePoseFactor& f = team_factors[next];
      if (r == self || f.a().robot == self) add(f, true);
      if (r == self) ++part.team_factors;
    }
  }
  for (const auto& [k, x] : robot.estimate()) part.initial.emplace(Relabel(k, local), x);
  for (const auto& s : shared) {
    const int a = s.alpha_object.robot, b = s.beta_object.robot;
    if (a == b || (a != self && b != self) || in_range.count(a) == 0 || in_range.count(b) == 0) {
      continue;
    }
    add(ObjectObjectFactor(s, lambda), false);
    ++part.object_object;
  }
  return part;
}

GroupUpdate RobotGroupUpdate(const std::vector<int>& robots, int robot, const Values& solution,
                             const std::vector<SharedObject>& shared, int step,
                             const std::set<int>& left) {
  const int local = LocalIndex(robots, robot, "RobotGroupUpdate");
  const auto value = [&](Key k) -> const SE3& {
    const auto it = solution.find(k);
    if (it == solution.end()) {
      throw InvalidInputError("RobotGroupUpdate: the solution has no value for " + ToString(k));
    }
    return it->second;
  };
  GroupUpdate u;
  u.robot = robot;
  const SE3 to_own = value(Key::Pose(local, 0)).inverse();
  for (const auto& [k, x] : solution) {
    if (k.robot == local) u.estimate.emplace(Relabel(k, robot), to_own * x);
  }
  u.estimate[Key::Pose(robot, 0)] = SE3();
  for (const auto& s : shared) {
    for (const auto& [mine, other] : {std::pair{s.alpha_object, s.beta_object},
                                      std::pair{s.beta_object, s.alpha_object}}) {
      if (mine.robot != robot || other.robot == robot) continue;
      const auto j = std::lower_bound(robots.begin(), robots.end(), other.robot);
      if (j == robots.end() || *j != other.robot) continue;
      const Key key = Relabel(other, static_cast<int>(j - robots.begin()));
      if (left.count(other.robot) && solution.count(key) == 0) continue;  // keeps its copy
      u.held[other] = {to_own * value(Relabel(other, static_cast<int>(j - robots.begin()))), step};
    }
  }
  return u;
}

}  // namespace moslam
