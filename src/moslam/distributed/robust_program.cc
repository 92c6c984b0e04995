#include "moslam/distributed/robust_program.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <set>
#include <string>
#include <utility>

#include "moslam/common/errors.h"
#include "moslam/distributed/messages.h"
#include "moslam/distributed/program_link.h"
#include "moslam/distributed/separator_check_program.h"

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

// The robust factors of one graph as a robot sees them: the weights it owns and, per neighbour
// (every robot a factor reaches), the robust separators to it in graph order.
struct RobustIndex {
  PoseGraph graph;
  std::vector<bool> robust;
  std::vector<std::size_t> owned;
  std::map<int, std::vector<std::size_t>> separators;
};

RobustIndex MakeIndex(int robot, PoseGraph graph, std::vector<bool> robust) {
  RobustIndex x;
  const std::vector<RelativePoseFactor>& factors = graph.factors();
  for (std::size_t i = 0; i < factors.size(); ++i) {
    const int a = factors[i].a().robot, b = factors[i].b().robot;
    if (a != b) x.separators[a == robot ? b : a];  // every neighbour has an entry
    if (!robust[i]) continue;
    if (std::min(a, b) == robot) x.owned.push_back(i);
    if (a != b) x.separators[a == robot ? b : a].push_back(i);
  }
  x.graph = std::move(graph);
  x.robust = std::move(robust);
  return x;
}

class RobustProgram {
 public:
  RobustProgram(const RobustRobotProblem& problem, const RobustProgramOptions& options,
                const AgentFactory& make_agent, TeamChannel& channel)
      : p_(problem), options_(options), make_agent_(make_agent), channel_(channel) {
    solver_ = options_.solver;
    solver_.refine = true;
    consistency_ = options_.consistency;
    if (consistency_.threshold == 0.0) consistency_.threshold = options_.gnc.threshold2();
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
      if (p_.checked.empty() || p_.checked[i]) list.push_back(i);
      shared_[a == p_.robot ? b : a].push_back(i);
    }
    full_ = MakeIndex(p_.robot, p_.subgraph, p_.robust);
  }

  RobustProgramResult run() {
    const std::size_t n = p_.subgraph.factors().size();
    values_ = p_.initial;
    const bool check = options_.check_separators;
    std::vector<bool> kept(n, true);
    if (check) kept = checkSeparators();
    if (check && check_rejected_by_team_ > 0.0 && !linked(kept)) {
      out_.unlinked = true;
      out_.weights.assign(n, 0.0);
      for (std::size_t i = 0; i < n; ++i) out_.weights[i] = kept[i] ? 1.0 : 0.0;
      for (const auto& [k, x] : p_.initial) {
        if (k.robot == p_.robot) out_.estimate[k] = x;
      }
      return std::move(out_);
    }
    // GNC on the graph the check kept (all of it without the check).
    std::vector<std::size_t> index;
    std::vector<bool> kept_robust;
    PoseGraph kept_graph = SubGraph(p_.subgraph, kept, &index);
    for (std::size_t i : index) kept_robust.push_back(p_.robust[i]);
    const RobustIndex gnc = MakeIndex(p_.robot, std::move(kept_graph), std::move(kept_robust));
    std::vector<double> w(index.size(), 1.0);
    solve(gnc.graph);
    GncSchedule schedule(options_.gnc);
    std::vector<double> r2 = SquaredResiduals(gnc.graph, values_);
    double max_r2 = 0.0;
    for (std::size_t i : gnc.owned) max_r2 = std::max(max_r2, r2[i]);
    const bool started = schedule.start(TeamMax(link_.reduce(max_r2), 0));
    if (started) {
      for (std::uint32_t k = 1;; ++k) {
        double undecided = 0.0;
        for (std::size_t i : gnc.owned) {
          w[i] = schedule.weight(r2[i]);
          if (!schedule.decided(w[i])) undecided += 1.0;
        }
        const double left = TeamSum(exchangeWeights(gnc, w, k, undecided), 0);
        solve(WeightedGraph(gnc.graph, w, options_.gnc.min_weight));
        r2 = SquaredResiduals(gnc.graph, values_);
        if (schedule.next(left == 0.0)) break;
      }
    }
    out_.status = schedule.status();
    out_.iterations = schedule.iterations();
    // Back to the whole subgraph: the separators the check left out weigh 0.
    out_.weights.assign(n, check ? 0.0 : 1.0);
    for (std::size_t j = 0; j < index.size(); ++j) out_.weights[index[j]] = w[j];
    const auto round = static_cast<std::uint32_t>(schedule.iterations() + 1);
    if (check) {
      // RunRobustDgs readmits and solves the inliers whether GNC ran or not.
      fetchLeftOut(kept);
      finish(OwnedResiduals(), round);
      if (options_.retest_left_out && out_.polished) retest(kept, round + 1);
    } else if (started) {
      finish(r2, round);
    }
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

  // Sends every neighbour the weights of the robust separators of `x` this robot owns toward it
  // (in graph order; none toward a lower robot), with `value` in the report, and takes the
  // weights of the separators its lower neighbours own from theirs.
  TeamStep exchangeWeights(const RobustIndex& x, std::vector<double>& weights,
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
        throw InvalidInputError(
            "robust program: robot " + std::to_string(other) + " sent " +
            std::to_string(m.weights.size()) + " weights for the " +
            std::to_string(it->second.size()) + " robust separators robot " +
            std::to_string(p_.robot) + " shares with it (their subgraphs disagree)");
      }
      for (std::size_t j = 0; j < m.weights.size(); ++j) weights[it->second[j]] = m.weights[j];
    }
    return got;
  }

  // The separator check (C1-C4 of the header): the kept flag of every factor of the subgraph.
  std::vector<bool> checkSeparators() {
    (void)make_agent_(p_.subgraph, values_);  // every neighbour reached (see AgentFactory)
    SeparatorCheckVerdict v = RunSeparatorCheck(p_, pairs_, consistency_, options_.gnc, link_);
    out_.check_rejected += v.rejected;
    out_.check_deferred += v.deferred;
    check_rejected_by_team_ = v.rejected_by_team;
    support_ = std::move(v.support);
    runner_up_ = std::move(v.runner_up);
    return std::move(v.kept);
  }

  // After GNC: the higher robot of each pair sends the lower its estimates of its variables in
  // the robust separators the check left out (empty messages elsewhere), for their residuals.
  void fetchLeftOut(const std::vector<bool>& kept) {
    sendEstimates([&](std::size_t i, const Key&) { return !kept[i] && p_.robust[i]; });
  }

  // One step: the higher robot of each pair sends the lower its estimates of its variable `mine`
  // in the separators i with select(i, mine) (empty messages elsewhere), each message counted
  // with the check. Returns the variables received, now among its copies.
  template <class Select>
  std::set<Key> sendEstimates(const Select& select) {
    (void)make_agent_(p_.subgraph, values_);  // every neighbour reached (see AgentFactory)
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

  // r^T Omega r of the robust factors it owns at the current estimate and copies (0 elsewhere).
  std::vector<double> OwnedResiduals() const {
    std::vector<double> r2(p_.subgraph.factors().size(), 0.0);
    for (std::size_t i : full_.owned) {
      const RelativePoseFactor& f = p_.subgraph.factors()[i];
      r2[i] = 2.0 * f.cost(values_.at(f.a()), values_.at(f.b()));
    }
    return r2;
  }

  // The readmission, and the inliers' solve when some weight is not 1 and the inliers link the
  // team.
  void finish(const std::vector<double>& r2, std::uint32_t round) {
    const double c2 = options_.gnc.threshold2();
    double changed = 0.0;  // readmitted or not one, of the weights it owns
    for (std::size_t i : full_.owned) {
      if (out_.weights[i] < 0.5 && r2[i] <= c2) {
        out_.weights[i] = 1.0;
        ++out_.readmitted;
        changed += 1.0;
      }
    }
    const std::vector<RelativePoseFactor>& factors = p_.subgraph.factors();
    for (std::size_t i = 0; i < factors.size(); ++i) {
      if (std::min(factors[i].a().robot, factors[i].b().robot) == p_.robot &&
          out_.weights[i] != 1.0) {
        changed += 1.0;
      }
    }
    if (TeamSum(exchangeWeights(full_, out_.weights, round, changed), 0) == 0.0) return;
    const std::vector<bool> inliers = Inliers(out_.weights);
    if (!linked(inliers)) return;
    const PoseGraph inlier_graph = SubGraph(p_.subgraph, inliers);
    const double before = ownedCost(inlier_graph);
    Values rounds = values_;
    solve(inlier_graph);
    TeamReport costs;
    costs.value[0] = before;
    costs.value[1] = ownedCost(inlier_graph);
    const TeamStep got = link_.step(costs);
    if (KeepInlierSolve(TeamSum(got, 0), TeamSum(got, 1))) {
      out_.polished = true;
      inlier_cost_ = TeamSum(got, 1);
    } else {
      values_ = std::move(rounds);
      out_.polish_refused = true;
    }
  }

  // F of the factors of `graph` it owns (its own, and its separators to robots of higher id) at
  // its estimate and copies: summed over the team, F of the team's graph.
  double ownedCost(const PoseGraph& graph) const {
    double cost = 0.0;
    for (const RelativePoseFactor& f : graph.factors()) {
      if (std::min(f.a().robot, f.b().robot) != p_.robot) continue;
      cost += f.cost(values_.at(f.a()), values_.at(f.b()));
    }
    return cost;
  }

  // Whether every live robot reaches robot 0 (or a prior) through the separators `inliers` marks:
  // each robot reports whether it does, step after step, until no report changes.
  bool linked(const std::vector<bool>& inliers) {
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

  // ---- the re-test of the check's rejects (RobustProgramOptions::retest_left_out) ----------
  // Whether an inlier (weight >= 0.5; every factor touching its variables is in the subgraph)
  // touches its variable `key`.
  bool held(const Key& key) const {
    const std::vector<RelativePoseFactor>& factors = p_.subgraph.factors();
    for (std::size_t i = 0; i < factors.size(); ++i) {
      if (out_.weights[i] >= 0.5 && (factors[i].a() == key || factors[i].b() == key)) return true;
    }
    return false;
  }

  // As RunRobustDgs: R1, the higher robot of each pair sends the lower its estimates of its
  // variables, held by inliers, in the robust separators the check left out and still rejected;
  // R2, the lower robot's candidates (support, both ends held) by r^T Omega r, then subgraph
  // order, and its groups (retest_groups: per neighbour of higher id, increasing, the separators
  // left out of the pair's runner-up set with both ends held); then per candidate, team-wide in
  // increasing r^T Omega r (ties: the lower robot), a trial (tryCandidate), and per group with
  // GroupMinimum or more members still rejected, team-wide in increasing (robot, neighbour), a
  // trial of all of them (tryGroup).
  void retest(const std::vector<bool>& kept, std::uint32_t round) {
    const std::vector<RelativePoseFactor>& factors = p_.subgraph.factors();
    const auto left_out = [&](std::size_t i) {
      return p_.robust[i] && !kept[i] && out_.weights[i] < 0.5;
    };
    const std::set<Key> held_there =
        sendEstimates([&](std::size_t i, const Key& mine) { return left_out(i) && held(mine); });
    std::vector<std::pair<double, std::size_t>> mine;
    std::vector<std::vector<std::size_t>> groups;
    for (const auto& [other, list] : pairs_) {
      if (other < p_.robot) continue;
      groups.emplace_back();
      for (std::size_t i : list) {
        const RelativePoseFactor& f = factors[i];
        const bool a_mine = f.a().robot == p_.robot;
        if (!left_out(i) || !held(a_mine ? f.a() : f.b()) ||
            !held_there.count(a_mine ? f.b() : f.a())) {
          continue;
        }
        if (runner_up_.count(i)) groups.back().push_back(i);
        const auto it = support_.find(i);
        if (it != support_.end() && it->second >= consistency_.min_support) {
          mine.emplace_back(2.0 * f.cost(values_.at(f.a()), values_.at(f.b())), i);
        }
      }
    }
    std::sort(mine.begin(), mine.end());
    std::size_t next = 0;
    double f0 = inlier_cost_;
    std::uint32_t k = round;
    for (;; ++k) {
      TeamReport offer;
      offer.value[0] = next < mine.size() ? 1.0 : 0.0;
      offer.value[1] = next < mine.size() ? mine[next].first : 0.0;
      const TeamStep offers = link_.step(offer);
      int chosen = -1;
      double best = 0.0;
      for (const auto& [r, o] : offers.reports) {  // robot id order: ties to the lower
        if (o.value[0] == 1.0 && (chosen < 0 || o.value[1] < best)) {
          chosen = r;
          best = o.value[1];
        }
      }
      if (chosen < 0) break;
      ++out_.retests;
      std::vector<std::size_t> candidate;
      if (chosen == p_.robot) candidate = {mine[next++].second};
      out_.retest_readmitted += tryCandidate(candidate, k, &f0);
    }
    if (!options_.retest_groups) return;
    std::size_t group = 0;
    for (++k;; ++k) {
      std::vector<std::size_t> left;
      for (; group < groups.size() && left.empty(); ++group) {
        for (std::size_t i : groups[group]) {
          if (out_.weights[i] < 0.5) left.push_back(i);
        }
        if (left.size() < GroupMinimum(consistency_.min_support)) left.clear();
      }
      TeamReport offer;
      offer.value[0] = static_cast<double>(left.size());
      const TeamStep offers = link_.step(offer);
      int chosen = -1;
      for (const auto& [r, o] : offers.reports) {  // robot id order: the lowest offering
        if (o.value[0] > 0.0) {
          chosen = r;
          break;
        }
      }
      if (chosen < 0) return;
      if (chosen != p_.robot && !left.empty()) --group;  // offered again in the next step
      ++out_.group_retests;
      if (chosen != p_.robot) left.clear();
      if (tryGroup(left, kept, &k)) {
        for (std::size_t i : left) out_.group_readmitted += out_.weights[i] >= 0.5 ? 1 : 0;
      }
    }
  }

  // One trial of the re-test, in step k: the separators of `candidate` (its own; empty on the
  // other robots) get weight 1, the weight step, the inliers' solve, a step reducing their cost
  // F1; they stay when 2 (F1 - F0) <= c2, F0 then F1; else every robot puts its weights and
  // estimate back. Returns how many of its own came back.
  int tryCandidate(const std::vector<std::size_t>& candidate, std::uint32_t k, double* f0) {
    const std::vector<double> weights = out_.weights;
    const Values values = values_;
    for (std::size_t i : candidate) out_.weights[i] = 1.0;
    // The candidate's robots need not be neighbours in the last solve: an agent of the whole
    // subgraph for the weight step (see AgentFactory).
    (void)make_agent_(p_.subgraph, values_);
    exchangeWeights(full_, out_.weights, k, 0.0);
    const PoseGraph trial = SubGraph(p_.subgraph, Inliers(out_.weights));
    solve(trial);
    TeamReport cost;
    cost.value[0] = ownedCost(trial);
    const double f1 = TeamSum(link_.step(cost), 0);
    if (std::isfinite(f1) && 2.0 * (f1 - *f0) <= options_.gnc.threshold2()) {
      *f0 = f1;
      return static_cast<int>(candidate.size());
    }
    out_.weights = weights;
    values_ = values;
    return 0;
  }

  // The trial of a group (RunRobustDgs's RetestGroup), from step *k on: the weights of its
  // robust factors to the truncated cost's (1 for an inlier, 0 else), the group's (its own;
  // empty on the other robots) 1, a weight step; the factors it may use (all but the check's
  // rejects still left out), a step in which the higher robot of each pair sends the lower its
  // estimates of its variables in them (for the truncated cost before); then solves of the
  // weighted factors it may use, each followed by a weight step with the weights it owns at the
  // result (1 within c2, else 0) and the team's count of changed ones, until none changed or
  // after retest_group_solves; a step reducing the truncated cost before and after. Kept when it
  // fell, else every robot puts its weights and estimate back.
  bool tryGroup(const std::vector<std::size_t>& group, const std::vector<bool>& kept,
                std::uint32_t* k) {
    const std::size_t n = p_.subgraph.factors().size();
    const double c2 = options_.gnc.threshold2();
    const std::vector<double> weights = out_.weights;
    const Values values = values_;
    for (std::size_t i = 0; i < n; ++i) {
      if (p_.robust[i]) out_.weights[i] = out_.weights[i] >= 0.5 ? 1.0 : 0.0;
    }
    for (std::size_t i : group) out_.weights[i] = 1.0;
    (void)make_agent_(p_.subgraph, values_);
    exchangeWeights(full_, out_.weights, *k, 0.0);
    std::vector<bool> usable(n);
    for (std::size_t i = 0; i < n; ++i) {
      usable[i] = !(p_.robust[i] && !kept[i] && out_.weights[i] < 0.5);
    }
    sendEstimates([&](std::size_t i, const Key&) { return usable[i]; });
    std::vector<std::size_t> index;
    const PoseGraph sub = SubGraph(p_.subgraph, usable, &index);
    std::vector<bool> sub_robust;
    for (std::size_t i : index) sub_robust.push_back(p_.robust[i]);
    const double before = ownedTruncatedCost(sub, sub_robust);
    for (int s = 0; s < options_.retest_group_solves; ++s) {
      std::vector<double> w;
      for (std::size_t i : index) w.push_back(out_.weights[i]);
      solve(WeightedGraph(sub, w, options_.gnc.min_weight));
      double changed = 0.0;
      for (std::size_t i : full_.owned) {
        if (!usable[i]) continue;
        const RelativePoseFactor& f = p_.subgraph.factors()[i];
        const double next = 2.0 * f.cost(values_.at(f.a()), values_.at(f.b())) <= c2 ? 1.0 : 0.0;
        if (next != out_.weights[i]) changed += 1.0;
        out_.weights[i] = next;
      }
      (void)make_agent_(p_.subgraph, values_);
      if (TeamSum(exchangeWeights(full_, out_.weights, ++*k, changed), 0) == 0.0) break;
    }
    TeamReport cost;
    cost.value[0] = before;
    cost.value[1] = ownedTruncatedCost(sub, sub_robust);
    const TeamStep got = link_.step(cost);
    const double after = TeamSum(got, 1);
    if (std::isfinite(after) && after < TeamSum(got, 0)) return true;
    out_.weights = weights;
    values_ = values;
    return false;
  }

  // The truncated cost of the factors of `graph` it owns (r^T Omega r / 2, a robust one's at most
  // c2 / 2) at its estimate and copies.
  double ownedTruncatedCost(const PoseGraph& graph, const std::vector<bool>& robust) const {
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

  const RobustRobotProblem& p_;
  const RobustProgramOptions& options_;
  const AgentFactory& make_agent_;
  TeamChannel& channel_;
  DgsOptions solver_;
  SeparatorConsistencyOptions consistency_;  // threshold resolved
  RobustIndex full_;                         // the whole subgraph's robust factors
  std::map<int, std::vector<std::size_t>> pairs_;  // per neighbour: every checked separator
  std::map<int, std::vector<std::size_t>> shared_;  // per neighbour: every separator
  double check_rejected_by_team_ = 0.0;  // separators the check left out, over the team
  Values values_;                                  // its estimate and copies
  std::map<std::size_t, int> support_;  // per separator it checked: the check's support
  std::set<std::size_t> runner_up_;     // the separators it checked in their pair's runner-up set
  double inlier_cost_ = 0.0;            // F of the inliers' solve, when kept
  RobustProgramResult out_;
  ProgramLink link_{p_.robot, channel_, out_};  // counts into out_
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
