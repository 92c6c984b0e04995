#include "moslam/distributed/robust_program.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <set>
#include <string>
#include <utility>

#include "moslam/common/errors.h"
#include "moslam/distributed/retest_program.h"
#include "moslam/distributed/robust_robot.h"
#include "moslam/distributed/separator_check_program.h"
#include "moslam/distributed/separator_consistency.h"
#include "moslam/robust/loop_consistency.h"

namespace moslam {

void RobustProgramOptions::validate() const {
  solver.validate();
  gnc.validate();
  if (retest_group_solves < 1) {
    throw InvalidInputError("RobustProgramOptions: retest_group_solves must be >= 1");
  }
  if (solver.order != SweepOrder::kJacobi) {
    throw InvalidInputError("RobustProgramOptions: solver.order must be Jacobi (the robots of a "
                            "team solve in parallel)");
  }
  if (check_separators) {
    if (!(consistency.threshold >= 0.0)) {
      throw InvalidInputError("RobustProgramOptions: consistency.threshold must be >= 0");
    }
    SeparatorConsistencyOptions c = consistency;
    if (c.threshold == 0.0) c.threshold = gnc.threshold2();
    c.validate();
  }
}

bool KeepInlierSolve(double cost_before, double cost_after) {
  return std::isfinite(cost_after) && cost_after <= cost_before * (1.0 + 1e-6) + 1e-12;
}

namespace {

class RobustProgram {
 public:
  RobustProgram(const RobustRobotProblem& problem, const RobustProgramOptions& options,
                const AgentFactory& make_agent, TeamChannel& channel)
      : p_(problem), options_(options), robot_(problem, options, make_agent, channel) {
    consistency_ = options_.consistency;
    if (consistency_.threshold == 0.0) consistency_.threshold = options_.gnc.threshold2();
  }

  RobustProgramResult run() {
    const std::size_t n = p_.subgraph.factors().size();
    RobustProgramResult& out = robot_.result();
    const bool check = options_.check_separators;
    SeparatorCheckVerdict verdict;
    verdict.kept.assign(n, true);
    if (check) {
      robot_.reachEveryNeighbour();
      const OwnCheck own = checkOwnLoopClosures();
      // Its map for the check: the checked factors but its own loop closures along its odometry
      // and those its own check rejected (CheckSeparators).
      RobustRobotProblem trusted = p_;
      trusted.checked = own.in_map;
      verdict = RunSeparatorCheck(trusted, robot_.checkedPairs(), consistency_, options_.gnc,
                                  robot_.link());
      for (std::size_t i = 0; i < n; ++i) verdict.kept[i] = verdict.kept[i] && own.kept[i];
      out.check_rejected += verdict.rejected + own.rejected;
      out.check_deferred += verdict.deferred;
    }
    const std::vector<bool>& kept = verdict.kept;
    if (check && verdict.rejected_by_team > 0.0 && !robot_.linked(kept)) {
      out.unlinked = true;
      out.weights.assign(n, 0.0);
      for (std::size_t i = 0; i < n; ++i) out.weights[i] = kept[i] ? 1.0 : 0.0;
      for (const auto& [k, x] : p_.initial) {
        if (k.robot == p_.robot) out.estimate[k] = x;
      }
      return std::move(out);
    }
    // GNC on the graph the check kept (all of it without the check).
    std::vector<std::size_t> index;
    std::vector<bool> kept_robust;
    PoseGraph kept_graph = SubGraph(p_.subgraph, kept, &index);
    for (std::size_t i : index) kept_robust.push_back(p_.robust[i]);
    const RobustIndex gnc =
        MakeRobustIndex(p_.robot, std::move(kept_graph), std::move(kept_robust));
    std::vector<double> w(index.size(), 1.0);
    robot_.solve(gnc.graph);
    GncSchedule schedule(options_.gnc);
    std::vector<double> r2 = SquaredResiduals(gnc.graph, robot_.values());
    double max_r2 = 0.0;
    for (std::size_t i : gnc.owned) max_r2 = std::max(max_r2, r2[i]);
    const bool started = schedule.start(TeamMax(robot_.link().reduce(max_r2), 0));
    if (started) {
      for (std::uint32_t k = 1;; ++k) {
        double undecided = 0.0;
        for (std::size_t i : gnc.owned) {
          w[i] = schedule.weight(r2[i]);
          if (!schedule.decided(w[i])) undecided += 1.0;
        }
        const double left = TeamSum(robot_.exchangeWeights(gnc, w, k, undecided), 0);
        robot_.solve(WeightedGraph(gnc.graph, w, options_.gnc.min_weight));
        r2 = SquaredResiduals(gnc.graph, robot_.values());
        if (schedule.next(left == 0.0)) break;
      }
    }
    out.status = schedule.status();
    out.iterations = schedule.iterations();
    // Back to the whole subgraph: the separators the check left out weigh 0.
    out.weights.assign(n, check ? 0.0 : 1.0);
    for (std::size_t j = 0; j < index.size(); ++j) out.weights[index[j]] = w[j];
    const auto round = static_cast<std::uint32_t>(schedule.iterations() + 1);
    if (check) {
      // RunRobustDgs readmits and solves the inliers whether GNC ran or not.
      fetchLeftOut(kept);
      finish(robot_.ownedResiduals(), round);
      if (options_.retest_left_out && out.polished) {
        RunRetests(robot_, verdict, inlier_cost_, round + 1);
      }
    } else if (started) {
      finish(r2, round);
    }
    for (std::size_t i = 0; i < n; ++i) {
      if (p_.robust[i] && out.weights[i] < 0.5) ++out.outliers;
    }
    const std::set<Key>& used = p_.subgraph.keys();
    for (const auto& [k, x] : robot_.values()) {
      if (k.robot == p_.robot) {
        out.estimate[k] = x;
      } else if (used.count(k)) {  // not the other robots' variables `initial` may hold
        out.neighbours[k] = x;
      }
    }
    return std::move(out);
  }

 private:
  // C5: its own loop closures (robust factors between two of its poses) checked through its own
  // odometry, as RunRobustDgs checks each robot's (CheckEachRobotsLoopClosures): nothing crosses
  // the network. Per factor of its subgraph: kept (true for those not checked), and whether its
  // map for C1 holds it (a checked factor, not one of its loop closures along its odometry nor one
  // it rejected), both computed on the checked factors as RunRobustDgs does (CheckOnMask).
  struct OwnCheck {
    std::vector<bool> kept, in_map;
    int rejected = 0;
  };
  OwnCheck checkOwnLoopClosures() const {
    const std::size_t n = p_.subgraph.factors().size();
    const std::vector<bool> all(n, true);
    std::vector<std::size_t> seen;  // the factors it checks, as RunRobustDgs (CheckOnMask)
    const PoseGraph sub = SubGraph(p_.subgraph, p_.checked.empty() ? all : p_.checked, &seen);
    std::vector<bool> robust;
    for (std::size_t i : seen) robust.push_back(p_.robust[i]);
    OdometryCheckOptions o;
    o.threshold = consistency_.threshold;
    o.min_support = consistency_.min_support;
    o.odometry_uncertainty = consistency_.map_uncertainty;
    const OdometryCheckResult part = CheckEachRobotsLoopClosures(sub, robust, o);
    OwnCheck own;
    own.kept = all;
    own.in_map.assign(n, false);
    own.rejected = part.rejected;
    for (std::size_t j = 0; j < seen.size(); ++j) {
      own.kept[seen[j]] = part.kept[j];
      own.in_map[seen[j]] = part.inMap(j);
    }
    return own;
  }

  // After GNC: the higher robot of each pair sends the lower its estimates of its variables in
  // the robust separators the check left out (empty messages elsewhere), for their residuals.
  void fetchLeftOut(const std::vector<bool>& kept) {
    robot_.sendEstimates([&](std::size_t i, const Key&) { return !kept[i] && p_.robust[i]; });
  }

  // The readmission, and the inliers' solve when some weight is not 1 and the inliers link the
  // team.
  void finish(const std::vector<double>& r2, std::uint32_t round) {
    RobustProgramResult& out = robot_.result();
    const double c2 = options_.gnc.threshold2();
    double changed = 0.0;  // readmitted or not one, of the weights it owns
    const std::vector<double> verdicts = out.weights;
    for (std::size_t i : robot_.index().owned) {
      if (out.weights[i] < 0.5 && r2[i] <= c2) out.weights[i] = 1.0;
    }
    if (options_.one_to_one_after_gnc) {
      std::vector<std::size_t> members;
      for (std::size_t i : robot_.index().owned) {
        if (p_.robust[i]) members.push_back(i);
      }
      KeepOneToOne(p_.subgraph.factors(), members, r2, &out.weights);
    }
    for (std::size_t i : robot_.index().owned) {
      if (verdicts[i] < 0.5 && out.weights[i] >= 0.5) {
        ++out.readmitted;
        changed += 1.0;
      }
    }
    const std::vector<RelativePoseFactor>& factors = p_.subgraph.factors();
    for (std::size_t i = 0; i < factors.size(); ++i) {
      if (std::min(factors[i].a().robot, factors[i].b().robot) == p_.robot &&
          out.weights[i] != 1.0) {
        changed += 1.0;
      }
    }
    if (TeamSum(robot_.exchangeWeights(robot_.index(), out.weights, round, changed), 0) == 0.0) {
      return;
    }
    const std::vector<bool> inliers = Inliers(out.weights);
    if (!robot_.linked(inliers)) return;
    const PoseGraph inlier_graph = SubGraph(p_.subgraph, inliers);
    const double before = robot_.ownedCost(inlier_graph);
    Values rounds = robot_.values();
    robot_.solve(inlier_graph);
    TeamReport costs;
    costs.value[0] = before;
    costs.value[1] = robot_.ownedCost(inlier_graph);
    const TeamStep got = robot_.link().step(costs);
    if (KeepInlierSolve(TeamSum(got, 0), TeamSum(got, 1))) {
      out.polished = true;
      inlier_cost_ = TeamSum(got, 1);
    } else {
      robot_.values() = std::move(rounds);
      out.polish_refused = true;
    }
  }

  const RobustRobotProblem& p_;
  const RobustProgramOptions& options_;
  RobustRobot robot_;
  SeparatorConsistencyOptions consistency_;  // threshold resolved
  double inlier_cost_ = 0.0;                 // F of the inliers' solve, when kept
};

}  // namespace

RobustProgramResult RunRobustRobotProgram(const RobustRobotProblem& problem,
                                          const RobustProgramOptions& options,
                                          const AgentFactory& make_agent, TeamChannel& channel) {
  options.validate();
  if (problem.robust.size() != problem.subgraph.factors().size()) {
    throw InvalidInputError("robust program: the robust mask has " +
                            std::to_string(problem.robust.size()) + " entries for " +
                            std::to_string(problem.subgraph.factors().size()) + " factors");
  }
  if (!problem.checked.empty() && problem.checked.size() != problem.subgraph.factors().size()) {
    throw InvalidInputError("robust program: the checked mask has " +
                            std::to_string(problem.checked.size()) + " entries for " +
                            std::to_string(problem.subgraph.factors().size()) + " factors");
  }
  if (!make_agent) throw InvalidInputError("robust program: no agent factory");
  return RobustProgram(problem, options, make_agent, channel).run();
}

}  // namespace moslam
