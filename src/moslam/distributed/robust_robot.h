// One robot's state in the robust program (robust_program.h) and the team steps that move it:
// its estimate and copies of its neighbours' variables, the weights of its subgraph's factors
// (in its RobustProgramResult), the solves of a weighted or inlier subgraph, the weight and
// estimate exchanges with its neighbours, the team's sums of the costs of the factors each robot
// owns, and the flood of whether every robot is linked to robot 0. The program's stages (the
// separator check, GNC and the readmission, the re-tests) are written on it. Internal to the
// robust program (robust_program.cc, retest_program.cc); tested through it
// (robust_program_test.cc).
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <map>
#include <set>
#include <vector>

#include "moslam/distributed/program_link.h"
#include "moslam/distributed/robust_program.h"

namespace moslam {

// The robust factors of one graph as a robot sees them: the weights it owns (its own factors and
// its separators to robots of higher id) and, per neighbour (every robot a factor reaches, with
// an entry even without a robust separator), the robust separators to it in wire order
// (WireOrder below).
struct RobustIndex {
  PoseGraph graph;
  std::vector<bool> robust;
  std::vector<std::size_t> owned;
  std::map<int, std::vector<std::size_t>> separators;
};

RobustIndex MakeRobustIndex(int robot, PoseGraph graph, std::vector<bool> robust);

// Two neighbours send each other per-separator values (weights, the check's verdicts) as lists
// by position, and each may list their separators in its own order (its own file): on the wire
// a list follows the canonical order of its factors (CanonicalBefore, pose_graph.h). Returns the
// positions of `list` (indices into graph.factors()) in that order.
std::vector<std::size_t> WireOrder(const PoseGraph& graph, const std::vector<std::size_t>& list);

class RobustRobot {
 public:
  // Throws InvalidInputError when the subgraph holds a factor that does not touch the robot.
  // Keeps references to all four arguments.
  RobustRobot(const RobustRobotProblem& problem, const RobustProgramOptions& options,
              const AgentFactory& make_agent, TeamChannel& channel);

  const RobustRobotProblem& problem() const { return p_; }
  const RobustProgramOptions& options() const { return options_; }
  int robot() const { return p_.robot; }
  double c2() const { return options_.gnc.threshold2(); }
  ProgramLink& link() { return link_; }
  // The result so far; its `weights` are the current weights of the subgraph's factors.
  RobustProgramResult& result() { return out_; }
  std::vector<double>& weights() { return out_.weights; }
  // Its estimate and copies of its neighbours' variables.
  Values& values() { return values_; }
  // The whole subgraph's robust factors.
  const RobustIndex& index() const { return full_; }
  // Per neighbour: the robust separators with it the check sees (every neighbour has an entry).
  const std::map<int, std::vector<std::size_t>>& checkedPairs() const { return pairs_; }

  // An agent of the whole subgraph, not solved, so that the next step reaches every neighbour
  // (see AgentFactory).
  void reachEveryNeighbour();
  // RunRobotProgram (with the refinement) on a new agent of `graph` from the current estimate
  // and copies; the agent's estimate and copies replace them (variables the graph lacks keep
  // theirs).
  void solve(const PoseGraph& graph);
  // One step: sends every neighbour the weights of the robust separators of `x` this robot owns
  // toward it (in graph order; none toward a lower robot), with `value` in the report, and takes
  // the weights of the separators its lower neighbours own from theirs. Throws InvalidInputError
  // when a neighbour sends a number of weights that does not match.
  TeamStep exchangeWeights(const RobustIndex& x, std::vector<double>& weights, std::uint32_t round,
                           double value);
  // One step: the higher robot of each pair sends the lower its estimates of its variable `mine`
  // in the separators i with select(i, mine) (empty messages elsewhere), each message counted
  // with the check. Returns the variables received, now among its copies.
  std::set<Key> sendEstimates(const std::function<bool(std::size_t, const Key&)>& select);
  // Whether every live robot reaches robot 0 (or a prior) through the separators `inliers`
  // marks: each robot reports whether it does, step after step, until no report changes.
  bool linked(const std::vector<bool>& inliers);

  // r^T Omega r of the robust factors it owns at the current estimate and copies (0 elsewhere).
  std::vector<double> ownedResiduals() const;
  // F of the factors of `graph` it owns at its estimate and copies: summed over the team, F of
  // the team's graph.
  double ownedCost(const PoseGraph& graph) const;
  // The truncated cost of the factors of `graph` it owns (r^T Omega r / 2, a robust one's at
  // most c2 / 2; `robust` per factor of `graph`).
  double ownedTruncatedCost(const PoseGraph& graph, const std::vector<bool>& robust) const;
  // Whether an inlier (weight >= 0.5; every factor touching its variables is in the subgraph)
  // touches its variable `key`.
  bool held(const Key& key) const;

 private:
  const RobustRobotProblem& p_;
  const RobustProgramOptions& options_;
  const AgentFactory& make_agent_;
  TeamChannel& channel_;
  DgsOptions solver_;  // options.solver with the refinement on
  RobustIndex full_;
  std::map<int, std::vector<std::size_t>> pairs_;   // per neighbour: the checked robust separators
  std::map<int, std::vector<std::size_t>> shared_;  // per neighbour: every separator
  Values values_;
  RobustProgramResult out_;
  ProgramLink link_{p_.robot, channel_, out_};  // counts into out_
};

}  // namespace moslam
