#include "moslam/distributed/robust_robot.h"

#include <algorithm>
#include <string>
#include <utility>

#include "moslam/common/errors.h"
#include "moslam/distributed/messages.h"

namespace moslam {

RobustIndex MakeRobustIndex(int robot, PoseGraph graph, std::vector<bool> robust) {
  RobustIndex x;
  const std::vector<RelativePoseFactor>& factors = graph.factors();
  for (std::size_t i = 0; i < factors.size(); ++i) {
    const int a = factors[i].a().robot, b = factors[i].b().robot;
    if (a != b) x.separators[a == robot ? b : a];  // every neighbour has an entry
    if (!robust[i]) continue;
    if (std::min(a, b) == robot) x.owned.push_back(i);
    if (a != b) x.separators[a == robot ? b : a].push_back(i);
  }
  for (auto& [other, list] : x.separators) {  // sent by position (exchangeWeights)
    std::vector<std::size_t> wire;
    for (std::size_t j : WireOrder(graph, list)) wire.push_back(list[j]);
    list = std::move(wire);
  }
  x.graph = std::move(graph);
  x.robust = std::move(robust);
  return x;
}

std::vector<std::size_t> WireOrder(const PoseGraph& graph, const std::vector<std::size_t>& list) {
  std::vector<RelativePoseFactor> listed;
  listed.reserve(list.size());
  for (std::size_t i : list) listed.push_back(graph.factors().at(i));
  return CanonicalOrder(listed);
}

RobustRobot::RobustRobot(const RobustRobotProblem& problem, const RobustProgramOptions& options,
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
    if (a == b) continue;
    std::vector<std::size_t>& list = pairs_[a == p_.robot ? b : a];  // every neighbour
    // The check tests the robust separators (a least-squares one is kept untested).
    if ((p_.checked.empty() || p_.checked[i]) && (p_.robust.empty() || p_.robust[i])) {
      list.push_back(i);
    }
    shared_[a == p_.robot ? b : a].push_back(i);
  }
  full_ = MakeRobustIndex(p_.robot, p_.subgraph, p_.robust);
  values_ = p_.initial;
}

void RobustRobot::reachEveryNeighbour() { (void)make_agent_(p_.subgraph, values_); }

void RobustRobot::solve(const PoseGraph& graph) {
  RobotAgent& agent = make_agent_(graph, values_);
  RobotProgramResult r = RunRobotProgram(agent, solver_, channel_);
  out_.channel_steps += r.channel_steps;
  out_.solves.push_back(std::move(r));
  for (const auto& [k, x] : agent.estimate()) values_[k] = x;
  for (const auto& [k, x] : agent.neighbourEstimates()) values_[k] = x;
}

TeamStep RobustRobot::exchangeWeights(const RobustIndex& x, std::vector<double>& weights,
                                      std::uint32_t round, double value) {
  std::vector<WeightMessage> send;
  for (const auto& [other, list] : x.separators) {
    std::vector<double> mine;
    if (other > p_.robot) {
      for (std::size_t i : list) mine.push_back(weights[i]);
    }
    send.push_back(link_.weightMessage(other, round, std::move(mine)));
  }
  TeamReport report;
  report.weights = true;
  report.value[0] = value;
  TeamStep got = link_.step(report, send);
  for (const auto& [other, m] : got.weights) {
    const auto it = x.separators.find(other);
    if (other > p_.robot || it == x.separators.end()) continue;
    if (m.weights.size() != it->second.size()) {
      throw InvalidInputError("robust program: robot " + std::to_string(other) + " sent " +
                              std::to_string(m.weights.size()) + " weights for the " +
                              std::to_string(it->second.size()) + " robust separators robot " +
                              std::to_string(p_.robot) +
                              " shares with it (their subgraphs disagree)");
    }
    for (std::size_t j = 0; j < m.weights.size(); ++j) weights[it->second[j]] = m.weights[j];
  }
  return got;
}

std::set<Key> RobustRobot::sendEstimates(
    const std::function<bool(std::size_t, const Key&)>& select) {
  reachEveryNeighbour();
  std::vector<OutgoingMessage> estimates;
  for (const auto& [other, list] : shared_) {
    OutgoingMessage o = link_.emptyMessageTo(other);
    if (other < p_.robot) {
      std::set<Key> keys;
      for (std::size_t i : list) {
        const RelativePoseFactor& f = p_.subgraph.factors()[i];
        const Key mine = f.a().robot == p_.robot ? f.a() : f.b();
        if (select(i, mine)) keys.insert(mine);
      }
      for (const Key& k : keys) o.message.appendPose(k, values_.at(k));
      if (!keys.empty()) link_.countCheck(EncodeMessage(o.message).size());
    }
    estimates.push_back(std::move(o));
  }
  TeamReport report;
  report.sent = true;
  const TeamStep got = link_.step(report, {}, estimates);
  std::set<Key> received;
  for (const Message& m : got.estimates) {
    if (m.sender < p_.robot) continue;
    for (std::size_t e = 0; e < m.keys.size(); ++e) {
      values_[m.keys[e]] = m.pose(e);
      received.insert(m.keys[e]);
    }
  }
  return received;
}

bool RobustRobot::linked(const std::vector<bool>& inliers) {
  std::set<int> linked_to;
  const std::vector<RelativePoseFactor>& factors = p_.subgraph.factors();
  for (std::size_t i = 0; i < factors.size(); ++i) {
    const int a = factors[i].a().robot, b = factors[i].b().robot;
    if (a != b && inliers[i]) linked_to.insert(a == p_.robot ? b : a);
  }
  // Robot 0 holds the gauge anchor; a robot with a prior is anchored by it (as UnreachableFrom).
  bool reached = p_.robot == 0 || !p_.subgraph.priors().empty();
  std::map<int, double> previous;
  while (true) {
    const std::map<int, double> flags = TeamValues(link_.reduce(reached ? 1.0 : 0.0), 0);
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
    previous = flags;
  }
}

std::vector<double> RobustRobot::ownedResiduals() const {
  std::vector<double> r2(p_.subgraph.factors().size(), 0.0);
  for (std::size_t i : full_.owned) {
    const RelativePoseFactor& f = p_.subgraph.factors()[i];
    r2[i] = 2.0 * f.cost(values_.at(f.a()), values_.at(f.b()));
  }
  return r2;
}

double RobustRobot::ownedCost(const PoseGraph& graph) const {
  double cost = 0.0;
  for (const RelativePoseFactor& f : graph.factors()) {
    if (std::min(f.a().robot, f.b().robot) != p_.robot) continue;
    cost += f.cost(values_.at(f.a()), values_.at(f.b()));
  }
  return cost;
}

double RobustRobot::ownedTruncatedCost(const PoseGraph& graph,
                                       const std::vector<bool>& robust) const {
  const double c2 = options_.gnc.threshold2();
  double cost = 0.0;
  for (std::size_t i = 0; i < graph.factors().size(); ++i) {
    const RelativePoseFactor& f = graph.factors()[i];
    if (std::min(f.a().robot, f.b().robot) != p_.robot) continue;
    const double r2 = 2.0 * f.cost(values_.at(f.a()), values_.at(f.b()));
    cost += 0.5 * (robust[i] ? std::min(r2, c2) : r2);
  }
  return cost;
}

bool RobustRobot::held(const Key& key) const {
  const std::vector<RelativePoseFactor>& factors = p_.subgraph.factors();
  for (std::size_t i = 0; i < factors.size(); ++i) {
    if (out_.weights[i] >= 0.5 && (factors[i].a() == key || factors[i].b() == key)) return true;
  }
  return false;
}

}  // namespace moslam
