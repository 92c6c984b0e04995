#include "moslam/distributed/robust_program.h"

#include <algorithm>
#include <map>
#include <set>
#include <string>
#include <utility>

#include "moslam/common/errors.h"
#include "moslam/distributed/messages.h"

namespace moslam {

void RobustProgramOptions::validate() const {
  solver.validate();
  gnc.validate();
  if (solver.order != SweepOrder::kJacobi) {
    throw InvalidInputError("RobustProgramOptions: solver.order must be Jacobi (the robots of a "
                            "team solve in parallel)");
  }
}

namespace {

class RobustProgram {
 public:
  RobustProgram(const RobustRobotProblem& problem, const RobustProgramOptions& options,
                const AgentFactory& make_agent, TeamChannel& channel)
      : p_(problem), options_(options), make_agent_(make_agent), channel_(channel) {
    solver_ = options_.solver;
    solver_.refine = true;
    const std::vector<RelativePoseFactor>& factors = p_.subgraph.factors();
    for (std::size_t i = 0; i < factors.size(); ++i) {
      const int a = factors[i].a().robot, b = factors[i].b().robot;
      if (a != p_.robot && b != p_.robot) {
        throw InvalidInputError("robust program: robot " + std::to_string(p_.robot) +
                                " given a factor between " + ToString(factors[i].a()) + " and " +
                                ToString(factors[i].b()));
      }
      if (a != b) separators_[a == p_.robot ? b : a];  // every neighbour has an entry
      if (!p_.robust[i]) continue;
      if (std::min(a, b) == p_.robot) owned_.push_back(i);
      if (a != b) separators_[a == p_.robot ? b : a].push_back(i);  // subgraph order
    }
  }

  RobustProgramResult run() {
    const std::size_t n = p_.subgraph.factors().size();
    out_.weights.assign(n, 1.0);
    values_ = p_.initial;
    solve(p_.subgraph);
    GncSchedule schedule(options_.gnc);
    std::vector<double> r2 = SquaredResiduals(p_.subgraph, values_);
    double max_r2 = 0.0;
    for (std::size_t i : owned_) max_r2 = std::max(max_r2, r2[i]);
    const bool started = schedule.start(TeamMax(reduce(max_r2), 0));
    if (started) {
      for (std::uint32_t k = 1;; ++k) {
        double undecided = 0.0;
        for (std::size_t i : owned_) {
          out_.weights[i] = schedule.weight(r2[i]);
          if (!schedule.decided(out_.weights[i])) undecided += 1.0;
        }
        const double left = TeamSum(exchangeWeights(k, undecided), 0);
        solve(WeightedGraph(p_.subgraph, out_.weights, options_.gnc.min_weight));
        r2 = SquaredResiduals(p_.subgraph, values_);
        if (schedule.next(left == 0.0)) break;
      }
    }
    out_.status = schedule.status();
    out_.iterations = schedule.iterations();
    if (started) finish(r2, static_cast<std::uint32_t>(schedule.iterations() + 1));
    for (std::size_t i = 0; i < n; ++i) {
      if (p_.robust[i] && out_.weights[i] < 0.5) ++out_.outliers;
    }
    const std::set<Key>& used = p_.subgraph.keys();
    for (const auto& [k, x] : values_) {
      if (k.robot == p_.robot) {
        out_.estimate[k] = x;
      } else if (used.count(k)) {  // not the other robots' variables `initial` may hold
        out_.neighbours[k] = x;
      }
    }
    return std::move(out_);
  }

 private:
  // RunRobotProgram on a new agent of `graph` from the current estimate and copies; the agent's
  // estimate and copies replace them (variables the graph lacks keep theirs).
  void solve(const PoseGraph& graph) {
    RobotAgent& agent = make_agent_(graph, values_);
    RobotProgramResult r = RunRobotProgram(agent, solver_, channel_);
    out_.channel_steps += r.channel_steps;
    out_.solves.push_back(std::move(r));
    for (const auto& [k, x] : agent.estimate()) values_[k] = x;
    for (const auto& [k, x] : agent.neighbourEstimates()) values_[k] = x;
  }

  TeamStep step(const TeamReport& report, const std::vector<WeightMessage>& weights = {}) {
    ++out_.channel_steps;
    return channel_.step(DgsStage::kRefine, {}, report, nullptr, weights);
  }

  TeamStep reduce(double value) {
    TeamReport mine;
    mine.value[0] = value;
    return step(mine);
  }


  // Sends every neighbour the weights of the robust separators this robot owns toward it (in
  // subgraph order; none toward a lower robot), with `value` in the report, and takes the weights
  // of the separators its lower neighbours own from theirs.
  TeamStep exchangeWeights(std::uint32_t round, double value) {
    std::vector<WeightMessage> send;
    for (const auto& [other, list] : separators_) {
      WeightMessage m;
      m.sender = p_.robot;
      m.receiver = other;
      m.round = round;
      if (other > p_.robot) {
        for (std::size_t i : list) m.weights.push_back(out_.weights[i]);
      }
      out_.weight_bytes += static_cast<std::int64_t>(EncodeWeightMessage(m).size());
      ++out_.weight_messages;
      send.push_back(std::move(m));
    }
    TeamReport mine;
    mine.weights = true;
    mine.value[0] = value;
    TeamStep got = step(mine, send);
    for (const auto& [other, m] : got.weights) {
      const auto it = separators_.find(other);
      if (other > p_.robot || it == separators_.end()) continue;
      if (m.weights.size() != it->second.size()) {
        throw InvalidInputError(
            "robust program: robot " + std::to_string(other) + " sent " +
            std::to_string(m.weights.size()) + " weights for the " +
            std::to_string(it->second.size()) + " robust separators robot " +
            std::to_string(p_.robot) + " shares with it (their subgraphs disagree)");
      }
      for (std::size_t j = 0; j < m.weights.size(); ++j) out_.weights[it->second[j]] = m.weights[j];
    }
    return got;
  }

  // The readmission, and the inliers' solve when some weight is not 1 and the inliers link the
  // team.
  void finish(const std::vector<double>& r2, std::uint32_t round) {
    const double c2 = options_.gnc.threshold2();
    double changed = 0.0;  // readmitted or not one, of the weights it owns
    for (std::size_t i : owned_) {
      if (out_.weights[i] < 0.5 && r2[i] <= c2) {
        out_.weights[i] = 1.0;
        ++out_.readmitted;
        changed += 1.0;
      }
    }
    for (std::size_t i : owned_) {
      if (out_.weights[i] != 1.0) changed += 1.0;
    }
    if (TeamSum(exchangeWeights(round, changed), 0) == 0.0) return;
    const std::vector<bool> inliers = Inliers(out_.weights);
    if (!linked(inliers)) return;
    solve(SubGraph(p_.subgraph, inliers));
    out_.polished = true;
  }

  // Whether every live robot reaches robot 0 (or a prior) through separators of weight >= 0.5:
  // each robot
  // reports whether it does, step after step, until no report changes.
  bool linked(const std::vector<bool>& inliers) {
    std::set<int> linked_to;
    for (const auto& [other, list] : separators_) {
      for (std::size_t i : list) {
        if (inliers[i]) linked_to.insert(other);
      }
    }
    // Robot 0 holds the gauge anchor; a robot with a prior is anchored by it (as UnreachableFrom).
    bool reached = p_.robot == 0 || !p_.subgraph.priors().empty();
    std::map<int, double> previous;
    while (true) {
      const TeamStep got = reduce(reached ? 1.0 : 0.0);
      std::map<int, double> flags;
      for (const auto& [r, report] : got.reports) flags[r] = report.value[0];
      if (flags == previous) {
        for (const auto& [r, f] : flags) {
          if (f == 0.0) return false;
        }
        return true;
      }
      for (int other : linked_to) {
        const auto it = flags.find(other);
        if (it != flags.end() && it->second == 1.0) reached = true;
      }
      previous = std::move(flags);
    }
  }

  const RobustRobotProblem& p_;
  const RobustProgramOptions& options_;
  const AgentFactory& make_agent_;
  TeamChannel& channel_;
  DgsOptions solver_;
  std::vector<std::size_t> owned_;                     // robust factors whose weight it owns
  // Per neighbour (every robot a factor of the subgraph reaches): the robust separators to it.
  std::map<int, std::vector<std::size_t>> separators_;
  Values values_;                                      // its estimate and copies
  RobustProgramResult out_;
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
  if (!make_agent) throw InvalidInputError("robust program: no agent factory");
  return RobustProgram(problem, options, make_agent, channel).run();
}

}  // namespace moslam
